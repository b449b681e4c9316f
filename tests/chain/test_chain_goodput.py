"""The chain's goodput (issue 35 item 8): with events waiting in the relay, the outstation's
logger (plc/PLC_SoeChain.st PLC_SoeLog) sends full records, up to uPerTransfer of them per
transfer, and the push way delivers at least 0.90 of the middle hop's registers per second
(mipbench.chain measures the same for `make bench`; docs/chain.md "Goodput")."""
from mipcosim.chain import (OUT_DONE, OUT_FAILED, PUSH_RECORDS, ChainSetup, SoeChain, SoeParams,
                            check_chain, script)
from mipcosim.sim import SEC, Radio


def saturated(workdir, n, per_transfer):
    """n events all in the relay before the start, the push way, realistic radio: (records
    handed over, transfers done) at the end."""
    st = ChainSetup(events=script(n, start_s=0.01, every_s=0.001), radio=Radio.realistic(),
                    params=SoeParams(timeout_ms=3000, retain=True, redundant=True,
                                     per_transfer=per_transfer),
                    handover="push", relay_capacity=1000)
    with SoeChain(st, workdir) as ch:
        assert ch.run_to_end(600 * SEC, settle_ns=0)
        rep = check_chain(ch)
        assert rep.problems == [] and rep.lost == 0 and rep.duplicated == 0, rep.problems
        return ch.mw32("cen", PUSH_RECORDS), ch.mw("out", OUT_DONE)


def test_a_backlog_goes_in_full_records_and_long_transfers(tmp_path):
    """300 entries. The first transfer starts as the first entry is stored and its one record
    takes the few entries stored by the time the sender asks for it. From then on the relay's
    backlog is in the logger: every record is full but the very last (the other 297 or so
    entries: 19 full records and the rest), in transfers of 4 records (5 transfers). The
    logger that fixed a transfer's entries when it started sent the entries stored meanwhile
    in part-filled records (23 records). The outstation's sender runs window 2: it asks for
    record 3 of a transfer while record 2 is in flight, 20 ms after record 2's chunk. In the
    second transfer the reader is still filling the logger from the relay then, so that
    record takes the rest (11 entries) and ends the transfer: one record and one transfer
    more than with window 1 (21 records in 6 transfers)."""
    records, transfers = saturated(tmp_path, 300, 4)
    assert (records, transfers) == (1 + 21, 1 + 6)


def test_push_way_costs_at_most_10_percent_of_the_middle_hop(tmp_path):
    from mipbench import chain as chain_bench
    hop = chain_bench.middle_hop_regs_per_s(tmp_path / "hop", 20)
    push = chain_bench.saturated_rate(tmp_path / "push", 300, handover="push") * chain_bench.REGS
    assert push / hop >= 0.90, f"{push:.0f} registers/s relay -> drivers vs {hop:.0f} middle hop"


def test_a_cold_central_gets_again_only_the_record_it_had_not_acknowledged(tmp_path):
    """A backlog in transfers of 8 records, the central restarted cold twice mid-transfer: the
    outstation's transfer fails (the central acknowledges 0). The records of it the central had
    acknowledged are at the SCADA (acknowledged after the hand-over) and are not sent again;
    only the record in hand at the restart comes twice: at most 15 entries a restart. Sending
    the whole transfer again gave up to 8 records' worth."""
    st = ChainSetup(events=script(400, start_s=0.01, every_s=0.001), radio=Radio.realistic(),
                    params=SoeParams(timeout_ms=3000, per_transfer=8), relay_capacity=1000)
    with SoeChain(st, tmp_path) as ch:
        for at_s in (5.0, 9.0):
            ch.run_until(int(at_s * SEC))
            ch.restart("cen", "cold")
        assert ch.run_to_end(600 * SEC)
        rep = check_chain(ch)
        failed = ch.mw("out", OUT_FAILED)
    assert rep.lost == 0 and rep.changed == 0 and failed >= 2, (rep.problems, failed)
    assert rep.duplicated == rep.restart_duplicates <= 2 * 15, rep.duplicated
