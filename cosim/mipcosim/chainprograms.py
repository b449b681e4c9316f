"""The chain's programs (issue 35): their runtime configs, parameters and status
words, and the relay events of a run with what the control system must receive
(cosim/mipcosim/chain.py runs them; mipdemo.chain (plc/demo.py --chain) and bench/mipbench/chain.py
use them too)."""
from __future__ import annotations

from dataclasses import dataclass

from mipprograms.image import program_files
from mipprograms.image_chain import (RELAY, SCADA, SOE_BASE, SOE_REGS, UNICOS_IMAGE,  # noqa: F401
                                     UNICOS_MARKER, driver, status_words)    # (the chain's API)

from . import programs as L

ORIGIN_MS = 1767225600000          # the relay's time stamp of virtual time 0 (2026-01-01 UTC)
PROGRAMS = {"out": "outstation_soe.st", "cen": "central_soe.st"}
PUSH_PROGRAM = "central_push.st"   # the central of the push way (MIP_UnicosEvents)
HELPERS = ["PLC_Logger.st", "PLC_SoeChain.st"]

# The status words %MW100.., defined once: the member order of PLC_T_SoeOutStatus,
# PLC_T_SoeCenStatus and PLC_T_SoePushStatus in plc/PLC_SoeChain.st, read from the ST by
# mipprograms.image_chain (stc's parser); looked up by name (wStoredLo -> STORED_LO), so a member
# the ST renames or drops is a KeyError here, not a silent shift.
_OUT, _CEN, _PUSH = ({L._const_name(m): a for m, a in status_words(n).items()}
                     for n in ("outstation_soe", "central_soe", "central_push"))
OUT_STORED, OUT_SENT, OUT_LEVEL, OUT_DONE, OUT_FAILED, OUT_ERROR, OUT_FLAGS, OUT_RETRANS = (
    _OUT[n] for n in ("STORED_LO", "SENT_LO", "LEVEL", "DONE", "FAILED", "ERROR", "FLAGS",
                      "RETRANS"))
CEN_RECORDS, CEN_PUT, CEN_ACKED, CEN_BAD_ACKS, CEN_BAD_RECORDS, CEN_DUP, CEN_FAILED, \
    CEN_FLAGS, CEN_QUEUED = (_CEN[n] for n in ("RECORDS_LO", "PUT_LO", "ACKED_LO", "BAD_ACKS",
                                               "BAD_RECORDS", "DUP", "FAILED", "FLAGS", "QUEUED"))
# plc/central_push.st
PUSH_RECORDS, PUSH_EVENTS, PUSH_FRAMES, PUSH_RETRIES, PUSH_PASSIVE, PUSH_DUP, PUSH_FAILED, \
    PUSH_FLAGS = (_PUSH[n] for n in ("RECORDS_LO", "EVENTS_LO", "FRAMES", "RETRIES", "PASSIVE",
                                     "DUP", "FAILED", "FLAGS"))

def program_sources(role, handover="pull"):
    """The st_lib files, the programs' helpers and the chain's program of `role` ("out" |
    "cen"; the central of the push way with handover "push"): the hand-written logic, then its
    generated image (plc/image/, which holds the CONFIGURATION)."""
    name = PUSH_PROGRAM if role == "cen" and handover == "push" else PROGRAMS[role]
    return (L.lib_sources() + [str(L.PLC_DIR / h) for h in HELPERS]
            + [str(p) for p in program_files(name[:-3])])


def relay_sections(cfg, port=15030, host="127.0.0.1"):
    """The outstation's device `relay`: 40601..40626 read into %IW300.., SOE_Control written from
    %QW300 (FC16 of one register), trigger policy (plc/outstation_soe.st; the addresses are the
    image's, mipprograms.image_chain.RELAY); added to cfg."""
    r = RELAY.addr
    cfg.add("device", "relay", host=host, port=port, unit_id=1)
    cfg.add("write", "soe_control", device="relay", start=SOE_BASE + 1, size=1, image=r("wWrVal"),
            policy="trigger", trigger=r("xWrTrig"), done=r("xWrDone"), error=r("xWrErr"),
            length=r("wWrLen"))
    cfg.add("read", "soe", device="relay", start=SOE_BASE, size=SOE_REGS, image=r("aRead"),
            policy="trigger", trigger=r("xRdTrig"), done=r("xRdDone"), error=r("xRdErr"),
            status=r("wRdSt"))
    return cfg


def slave_section(cfg, port=0, host="127.0.0.1"):
    """The central's Modbus slave for the SCADA: SOE_Control's writes counted (MIP_SoeServer;
    the addresses are the image's, mipprograms.image_chain.SCADA)."""
    cfg.add("slave", host=host, port=port, watch=SCADA.addr("wCtrlWritten"),
            watch_count=SCADA.addr("wCtrlWrites"))
    return cfg


def unicos_sections(cfg, ports=(15040, 15041), host="127.0.0.1"):
    """The push central's devices unicos_a / unicos_b (WinCC OA's redundant pair of UNICOS
    drivers) and its write ranges: FC16 of the frame at the marker, trigger policy (the
    addresses are the image's, mipprograms.image_chain.driver)."""
    for d, port in zip("ab", ports):
        r = driver(d).addr
        cfg.add("device", f"unicos_{d}", host=host, port=port, unit_id=1)
        cfg.add("write", f"unicos_{d}", device=f"unicos_{d}", start=UNICOS_MARKER, size=123,
                image=r("aWrite"), policy="trigger", trigger=r("xWrTrig"),
                done=r("xWrDone"), error=r("xWrErr"), status=r("wWrSt"), length=r("wWrLen"))
    return cfg


def central_push_config(mdp_port=15020, unicos_ports=(15040, 15041), retain=None, host="127.0.0.1"):
    return unicos_sections(L.central_model(
        mdp_port, 1, host, comment="the chain (plc/central_push.st): also WinCC OA's UNICOS "
        "drivers A and B.", retain=retain), unicos_ports, host).text()


def outstation_soe_config(trm_port=15021, relay_port=15030, retain=None, host="127.0.0.1"):
    return relay_sections(L.outstation_model(
        trm_port, host, comment="the chain (plc/outstation_soe.st): also the relay's event "
        "recorder.", retain=retain), relay_port, host).text()


def central_soe_config(mdp_port=15020, slave_port=0, retain=None, host="127.0.0.1"):
    return slave_section(L.central_model(
        mdp_port, 1, host, comment="the chain (plc/central_soe.st): also the SCADA's Modbus "
        "slave.", retain=retain), slave_port, host).text()


@dataclass
class SoeParams:
    """%MW0..6 of the chain's programs (PLC_T_SoeParams in plc/PLC_SoeChain.st)."""
    per_record: int = 15          # relay entries per MIP record (1..15)
    per_transfer: int = 8         # records per transfer at most: 8 x 15 entries fill at most half
                                  # PLC_SoeLog's ring of 256, so the next transfer's entries are
                                  # there when one ends (our choice, issue 35 item 8)
    retain: bool = False          # the blocks' xRetained (warm restarts)
    ack_on_receipt: bool = False  # the central acknowledges a record once queued, not after the SCADA (measurement)
    redundant: bool = False       # push: a redundant pair of drivers (both get every frame)
    active_b: bool = False        # push: driver B is the active one
    timeout_ms: int = 300
    max_retries: int = 0
    ack_timeout_s: int = 0

    def words(self):
        flags = ((1 if self.retain else 0) | (2 if self.ack_on_receipt else 0)
                 | (4 if self.redundant else 0) | (8 if self.active_b else 0))
        return [1, self.per_record, self.per_transfer, flags, self.timeout_ms, self.max_retries,
                self.ack_timeout_s]


def script(n, start_s=0.5, every_s=0.05, seed=1):
    """n relay events, one every `every_s` seconds from start_s: (t_s, [type/bit, address,
    cause/type, value]); the words vary with n and seed, so a swapped, repeated or changed entry
    shows."""
    out = []
    for k in range(n):
        x = (k * 2654435761 + seed * 40503) & 0xFFFFFFFF
        out.append((start_s + k * every_s,
                    [0x0100 + (x >> 4) % 16, 1 + (x >> 8) % 1000, 0x0101 + (x >> 20) % 3, k & 0xFFFF]))
    return out


def expected(events, origin_ms=ORIGIN_MS):
    """What the SCADA must take, in order: (type/bit, address, cause/type, value, time stamp ms)."""
    return [(*w, origin_ms + int(round(t * 1e9)) // 1_000_000) for t, w in events]
