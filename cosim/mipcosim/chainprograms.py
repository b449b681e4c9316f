"""The chain's programs (issue 35): their runtime configs, parameters and status
words, and the relay events of a run with what the control system must receive
(cosim/mipcosim/chain.py runs them; mipdemo.chain (plc/demo.py --chain) and bench/mipbench/chain.py
use them too)."""
from __future__ import annotations

from dataclasses import dataclass

from . import programs as L

ORIGIN_MS = 1767225600000          # the relay's time stamp of virtual time 0 (2026-01-01 UTC)
SOE_BASE = 600                     # PDU address of 40601, at the relay and at the central
PROGRAMS = {"out": "outstation_soe.st", "cen": "central_soe.st"}
PUSH_PROGRAM = "central_push.st"   # the central of the push way (MIP_UnicosEvents)
UNICOS_MARKER = 0xFF80             # the frames' reference number (plc/gen_programs.py)
UNICOS_IMAGE = {"a": 400, "b": 530}
HELPERS = ["PLC_Logger.st", "PLC_SoeChain.st"]

# status words %MW100.. of the chain's programs (plc/gen_programs.py soe_status)
OUT_STORED, OUT_SENT, OUT_LEVEL, OUT_DONE, OUT_FAILED, OUT_ERROR, OUT_FLAGS, OUT_RETRANS = \
    100, 102, 104, 105, 106, 107, 108, 109
CEN_RECORDS, CEN_PUT, CEN_ACKED, CEN_BAD_ACKS, CEN_BAD_RECORDS, CEN_DUP, CEN_FAILED, \
    CEN_FLAGS, CEN_QUEUED = 100, 102, 104, 106, 107, 108, 109, 110, 111
# plc/central_push.st
PUSH_RECORDS, PUSH_EVENTS, PUSH_FRAMES, PUSH_RETRIES, PUSH_PASSIVE, PUSH_DUP, PUSH_FAILED, \
    PUSH_FLAGS = 100, 102, 104, 105, 106, 107, 108, 109


def program_sources(role, handover="pull"):
    """The st_lib files, the programs' helpers and the chain's program of `role` ("out" |
    "cen"; the central of the push way with handover "push")."""
    name = PUSH_PROGRAM if role == "cen" and handover == "push" else PROGRAMS[role]
    return (L.lib_sources() + [str(L.PLC_DIR / h) for h in HELPERS]
            + [str(L.PLC_DIR / name)])


def relay_sections(cfg, port=15030, host="127.0.0.1"):
    """The outstation's device `relay`: 40601..40626 read into %IW300.., SOE_Control written from
    %QW300 (FC16 of one register), trigger policy (plc/outstation_soe.st); added to cfg."""
    cfg.add("device", "relay", host=host, port=port, unit_id=1)
    cfg.add("write", "soe_control", device="relay", start=SOE_BASE + 1, size=1, image="%QW300",
            policy="trigger", trigger="%QX2.1", done="%IX2.2", error="%IX2.3", length="%QW2")
    cfg.add("read", "soe", device="relay", start=SOE_BASE, size=26, image="%IW300",
            policy="trigger", trigger="%QX2.0", done="%IX2.0", error="%IX2.1", status="%IW12")
    return cfg


def slave_section(cfg, port=0, host="127.0.0.1"):
    """The central's Modbus slave for the SCADA: SOE_Control's writes counted (MIP_SoeServer)."""
    cfg.add("slave", host=host, port=port, watch=f"%QW{SOE_BASE + 1}", watch_count="%IW9")
    return cfg


def unicos_sections(cfg, ports=(15040, 15041), host="127.0.0.1"):
    """The push central's devices unicos_a / unicos_b (WinCC OA's redundant pair of UNICOS
    drivers) and its write ranges: FC16 of the frame at the marker, trigger policy."""
    for k, (d, port) in enumerate(zip("ab", ports)):
        cfg.add("device", f"unicos_{d}", host=host, port=port, unit_id=1)
        cfg.add("write", f"unicos_{d}", device=f"unicos_{d}", start=UNICOS_MARKER, size=123,
                image=f"%QW{UNICOS_IMAGE[d]}", policy="trigger", trigger=f"%QX3.{k}",
                done=f"%IX3.{2 * k}", error=f"%IX3.{2 * k + 1}", status=f"%IW{13 + k}",
                length=f"%QW{3 + k}")
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
    """%MW0..6 of the chain's programs (plc/gen_programs.py SOE_PARAMS)."""
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
