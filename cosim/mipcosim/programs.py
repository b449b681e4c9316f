"""The example programs (plc/) as the co-simulation runs them: their register layout (plc/README.md),
the logger's data, their runtime configs and st_lib's files in import order."""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from mipprobe.regmap import MDP810, TRM810
from mipprograms.image import SND_OFFSET, WIN_OFFSET, status_members
from mipprograms.image import program_files
from mipprograms.image_many import STATS_BASE, stats_members
from plcharness.config import Config, Section

from .libraries import LIBRARIES, all_files, library_files

REPO = Path(__file__).resolve().parents[2]
PLC_DIR = REPO / "plc"
ST_LIB = REPO / "st_lib"
if (Path(__file__).resolve().parent / "_st_lib").is_dir():
    ST_LIB = Path(__file__).resolve().parent / "_st_lib"     # installed by the test kit (kit/)
# st_lib's two libraries (core, then chain) in their import order, read from the one order file
# of each library (st_lib/<library>/import-order.txt, mipcosim.libraries): paths relative to
# ST_LIB (core/MIP_Types.st, ...), the lists the Python tools build from (tests, docs, benchmarks)
CORE_FILES = library_files("core", ST_LIB)
CHAIN_FILES = library_files("chain", ST_LIB)
LIB_FILES = CORE_FILES + CHAIN_FILES
TYPES_ST = ST_LIB / "core" / "MIP_Types.st"       # the core's types (E_MIP_Error, ...)
MAX_STATIONS = 4
WINDOW = 160
FFFF = 0xFFFF

# The %MW words, defined once: the order of the members of PLC_T_Params, PLC_T_RcvStatus and
# PLC_T_SndStatus in plc/PLC_Logger.st (member k at the block's base + k), read from the ST by
# mipprograms.image (stc's parser). wTotalLo -> P_TOTAL_LO, wRecLo -> R_REC_LO, ...


def _const_name(member):
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", member[1:]).upper()


PARAM_WORDS = {_const_name(m): k for k, m in enumerate(status_members("par"))}
RCV_WORDS = {_const_name(m): k for k, m in enumerate(status_members("rcv"))}
S_BASE = SND_OFFSET
SND_WORDS = {_const_name(m): S_BASE + k for k, m in enumerate(status_members("snd"))}
W_BASE = WIN_OFFSET
# looked up by name (a member the ST renames or drops is a KeyError here, not a silent shift)
P_START, P_TOTAL_LO, P_TOTAL_HI, P_PER_TRANSFER, P_PAYLOAD, P_SESSION, P_STATION, P_FLAGS, \
    P_LOG_PERIOD, P_TIMEOUT, P_CHUNK, P_TRANSFER_TIMEOUT, P_MAX_RETRIES, P_CYCLIC_WRITE, \
    P_START_LO, P_START_HI = (PARAM_WORDS[n] for n in (
        "START", "TOTAL_LO", "TOTAL_HI", "PER_TRANSFER", "PAYLOAD", "SESSION", "STATION", "FLAGS",
        "LOG_PERIOD", "TIMEOUT", "CHUNK_SIZE", "TRANSFER_TIMEOUT", "MAX_RETRIES", "CYCLIC_WRITE",
        "START_LO", "START_HI"))
R_SEQ, R_FLAGS, R_NUMBER, R_LEN, R_ERROR, R_REC_LO, R_REC_HI, R_COM_LO, R_COM_HI, R_SUM_A, \
    R_SUM_B, R_TRANSFERS, R_FAILED, R_DUP, R_UNEXP, R_OPEN_LO, R_OPEN_HI, R_OFFERED, \
    R_TAKEN = (RCV_WORDS[n] for n in (
        "SEQ", "FLAGS", "NUMBER", "LEN", "ERROR", "REC_LO", "REC_HI", "COM_LO", "COM_HI", "SUM_A",
        "SUM_B", "TRANSFERS", "FAILED", "DUP", "UNEXP", "OPEN_LO", "OPEN_HI", "OFFERED", "TAKEN"))
S_SEQ, S_FLAGS, S_ERROR, S_LOG_LO, S_LOG_HI, S_OUT_LO, S_OUT_HI, S_DONE, S_FAILED, S_RETRANS, \
    S_ALL = (SND_WORDS[n] for n in ("SEQ", "FLAGS", "ERROR", "LOG_LO", "LOG_HI", "OUT_LO", "OUT_HI",
                                    "DONE", "FAILED", "RETRANS", "ALL"))
F_POLLED, F_STATIC, F_CYCLIC, F_RETAIN, F_WINDOW2, F_HANDOVER = 1, 2, 4, 8, 16, 32
# F_RETAIN: the blocks' xRetained (W1, W2); F_WINDOW2: MIP_Sender's uWindow 2 (P27);
# F_HANDOVER: the central acknowledges a record only once the control system took it
# (PLC_HandOver: R_OFFERED / R_TAKEN)


class EnumError(Exception):
    pass


_ENUM = re.compile(r"\b([A-Za-z_]\w*)\s*:\s*\(([^;]*?)\)\s*;", re.S)


@lru_cache(maxsize=None)
def st_enums(path: str | Path = TYPES_ST) -> dict[str, list[str]]:
    """The enumerated types of an ST file, {type name: [value names in order]}: a value's
    number is its index (IEC 61131-3 leaves it to the implementation; matiec, stc and the PLCs
    we target number from 0). The one reader of the numbers st_lib's E_MIP_* outputs carry
    (cosim, docs/tools/chainsim.py, the tests); nothing in Python copies them by hand."""
    text = Path(path).read_text(encoding="utf-8")
    text = re.sub(r"\(\*.*?\*\)", " ", text, flags=re.S)
    out = {}
    for block in re.findall(r"\bTYPE\b(.*?)\bEND_TYPE\b", text, re.S):
        for name, body in _ENUM.findall(block):
            values = [v.strip() for v in body.split(",")]
            if not all(re.fullmatch(r"[A-Za-z_]\w*", v) for v in values):
                raise EnumError(f"{path}: enum {name}: values with explicit numbers or "
                                f"not plain names are not supported")
            out[name] = values
    if not out:
        raise EnumError(f"{path}: no enumerated type found")
    return out


def enum_values(type_name: str, path: str | Path = TYPES_ST) -> dict[str, int]:
    """{value name: number} of one enumerated type of st_lib (e.g. E_MIP_Error)."""
    enums = st_enums(path)
    if type_name not in enums:
        raise EnumError(f"{path}: no enumerated type {type_name}")
    return {v: i for i, v in enumerate(enums[type_name])}


# E_MIP_Error's names without the MIP_ERR_ prefix, by number
ERRORS = [v.removeprefix("MIP_ERR_") for v in st_enums()["E_MIP_Error"]]


def error_name(code):
    return ERRORS[code] if 0 <= code < len(ERRORS) else f"#{code}"


def committed_positions(blk):
    """Stream positions whose committed registers the receiver's window still holds, given the
    peer block `blk` (at least offsets 0..R_OPEN_HI). PLC_RecordStore writes the open transfer
    into the same ring after the committed registers, so a transfer that opened after the last
    commit has overwritten the oldest ones: only the positions above committed + open - WINDOW
    are committed data."""
    committed = blk[R_COM_LO] + (blk[R_COM_HI] << 16)
    open_ = blk[R_OPEN_LO] + (blk[R_OPEN_HI] << 16)
    return range(max(0, committed + open_ - WINDOW), committed)


def peer_base(s):
    return 100 + 200 * (s - 1)


def read_image(s):
    return 100 + 125 * (s - 1)


def write_image(s):
    return 100 + 123 * (s - 1)


def lib_sources(libs=LIBRARIES) -> list[str]:
    """st_lib's files (paths) of the given libraries (default both: the core, then the chain
    library), each in its import order: what a build takes before the programs."""
    return [str(ST_LIB / f) for f in all_files(ST_LIB, libs)]


def program_sources(role: str, bidi: bool):
    """The files of plc/'s program `role` (outstation, central, central_many; bidi: the
    _bidi variant) in compile order: st_lib, the helpers, the hand-written program and its
    generated image (plc/image/, which holds the CONFIGURATION)."""
    name = f"{role}{'_bidi' if bidi else ''}"
    return lib_sources(("core",)) + [str(PLC_DIR / "PLC_Logger.st")] + \
        [str(p) for p in program_files(name)]


def log_value(n, j, session, station):
    """Register j of logger record n: the same function as PLC_LogValue in plc/PLC_Logger.st."""
    if j == 0:
        return n % 65536
    if j == 1:
        return (n // 65536) % 65536
    if j == 2:
        return session
    return ((n % 65536) * 7919 + j * 613 + session * 31 + station * 4099) % 65536


def log_record(n, payload, session, station):
    return [log_value(n, j, session, station) for j in range(payload)]


def fletcher(words, a=0, b=0):
    for v in words:
        a = (a + v) % 65521
        b = (b + a) % 65521
    return a, b


@dataclass
class Params:
    """What %MW0..13 hold (plc/README.md)."""
    records: int = 5
    per_transfer: int = 0
    payload: int = 16
    session: int = 1
    station: int = 1
    polled: bool = False
    static: bool = False
    cyclic: bool = False
    retain: bool = False    # the blocks wait for a snapshot before each new record / acknowledgement
    window: int = 1         # MIP_Sender's uWindow: 2 pipelines (P27)
    handover: bool = False  # the central: acknowledge a record once the control system took it
    log_period_ms: int = 0
    timeout_ms: int = 2000
    chunk: int = 123
    transfer_timeout_s: int = 0
    max_retries: int = 0
    start: int = 0          # records already read out (a restarted outstation resumes there)
    down_start: tuple = (0, 0, 0, 0)   # the same for the central's own streams, per station

    def words(self, start=True):
        flags = (F_POLLED if self.polled else 0) | (F_STATIC if self.static else 0) | \
                (F_CYCLIC if self.cyclic else 0) | (F_RETAIN if self.retain else 0) | \
                (F_WINDOW2 if self.window >= 2 else 0) | (F_HANDOVER if self.handover else 0)
        values = {"START": 1 if start else 0, "TOTAL_LO": self.records % 65536,
                  "TOTAL_HI": self.records // 65536, "PER_TRANSFER": self.per_transfer,
                  "PAYLOAD": self.payload, "SESSION": self.session, "STATION": self.station,
                  "FLAGS": flags, "LOG_PERIOD": self.log_period_ms, "TIMEOUT": self.timeout_ms,
                  "CHUNK_SIZE": self.chunk, "TRANSFER_TIMEOUT": self.transfer_timeout_s,
                  "MAX_RETRIES": self.max_retries, "CYCLIC_WRITE": 0,
                  "START_LO": self.start % 65536, "START_HI": self.start // 65536}
        for s, d in enumerate(self.down_start, 1):
            values[f"DOWN_START{s}_LO"], values[f"DOWN_START{s}_HI"] = d % 65536, d // 65536
        words = [0] * len(PARAM_WORDS)
        for name, k in PARAM_WORDS.items():
            words[k] = values[name]      # KeyError: a parameter of PLC_T_Params with no value here
        return words

    def effective_payload(self, bidi):
        room = self.chunk - (2 if bidi else 1)
        return max(1, min(self.payload, room))


# The request channel of the vendor stand-ins (standins/*/): station 1's ranges take their
# address, quantity and unit id from these %QW words (runtime_shim README, "A request channel";
# the stand-ins declare the same words)
CHANNEL_READ_ADDR, CHANNEL_READ_LEN, CHANNEL_WRITE_ADDR, CHANNEL_UNIT = 61, 62, 63, 64


def _channel_keys(s, write):
    """The address / length keys of station s's range when it is the stand-ins' channel."""
    if write:
        return {"address": f"%QW{CHANNEL_WRITE_ADDR}"}
    return {"address": f"%QW{CHANNEL_READ_ADDR}", "length": f"%QW{CHANNEL_READ_LEN}"}


def _read_write_ranges(cfg, dev, s, read_start, write_start, status_first=False, channel=False):
    """The device's write range, then its read range: requests run in config order, so a
    record or an acknowledgement the program raised in the same scan as the next read reaches
    the modem first (on a serial line a status read in front of it costs 14 ms at 19,200 baud,
    docs/serial.md). status_first: False, True ("yes": status and count alone) or the number
    of registers of the first read (3: an acknowledgement of one register comes in it)."""
    sf = ("yes" if status_first is True else status_first) if status_first else None
    cfg.add("write", f"{dev}_write", device=dev, start=write_start, size=123,
            image=f"%QW{write_image(s)}", policy="trigger", trigger=f"%QX{s}.1",
            done=f"%IX{s}.2", error=f"%IX{s}.3", status=f"%IW{20 + s}", length=f"%QW{s}",
            **(_channel_keys(s, True) if channel else {}))
    cfg.add("read", f"{dev}_read", device=dev, start=read_start, size=125, status_first=sf,
            image=f"%IW{read_image(s)}", policy="trigger", trigger=f"%QX{s}.0",
            done=f"%IX{s}.0", error=f"%IX{s}.1", status=f"%IW{10 + s}",
            **(_channel_keys(s, False) if channel else {}))


MASTER = {"timeout": "1s", "reconnect_min": "100ms", "reconnect_max": "1s"}   # [master]


def _config(comment, own):
    """A Config with its comment lines (own, then the caller's) and the [master] section."""
    cfg = Config(comment="\n".join(c for c in (own, comment) if c))
    cfg.add("master", **MASTER)
    return cfg


def _add_retain(cfg, retain):
    if retain:
        cfg.add("retain", **retain.keys)


# The durability handshake of the RETAIN snapshots (docs/retain.md#durability-handshake), the
# same addresses in every program: the program sets RETAIN_REQUEST to have a snapshot taken at
# the end of the scan; RETAIN_SAVED counts the completed snapshots since the start (mod 65536).
RETAIN_REQUEST = "%QX8.0"
RETAIN_SAVED = "%IW8"


def retain_section(file, period_ms=1000):
    """The [retain] section: snapshots in `file` every period_ms of scan time and on request
    (pass as retain= to the configs below)."""
    return Section("retain", keys={"file": str(file), "period": f"{period_ms}ms",
                                   "request": RETAIN_REQUEST, "saved": RETAIN_SAVED})


# The read strategy on a serial line (docs/serial.md, measured best): the first read of a MIP
# read area takes status, count and one data register (status_first = 3), so an
# acknowledgement of one register comes in the status read itself; the data only when bit 0
# announces a longer block. The demo and mip-cosim use it with --link rtu:BAUD.
RTU_STATUS_FIRST = 3


def serial_keys(path, baud=19200, parity="even", data_bits=8, stop_bits=1):
    """The [device] keys of a Modbus RTU link (instead of host / port): pass as `serial=` to
    outstation_config / central_config (issue 27, docs/serial.md)."""
    return {"serial": str(path), "baud": baud, "parity": parity, "data_bits": data_bits,
            "stop_bits": stop_bits}


def _link(serial, host, port, fc23):
    return {**(serial or {"host": host, "port": port}), **({"fc23": "yes"} if fc23 else {})}


def outstation_model(trm_port, host="127.0.0.1", comment="", retain=None, serial=None, unit=1,
                     status_first=False, fc23=False, channel=False):
    """The outstation's plcrt config (plcharness.config.Config). comment: lines of text
    written as comments. retain: a retain_section(...) or None. serial: serial_keys(...) for
    an RTU link (then trm_port and host are not used), unit: the TRM's unit id. channel: the
    ranges are the vendor stand-ins' request channel (the program sets address, quantity and
    unit id)."""
    if channel:
        unit = f"%QW{CHANNEL_UNIT}"
    cfg = _config(comment, "plcrt config of the outstation (plc/outstation*.st): the TRM-810 of "
                  "its station.")
    cfg.add("device", "trm", **_link(serial, host, trm_port, fc23), unit_id=unit,
            errors="%IW30", online="%IX9.0")
    _read_write_ranges(cfg, "trm", 1, TRM810.read_status, TRM810.write_data, status_first, channel)
    _add_retain(cfg, retain)
    return cfg


def outstation_config(*args, **kw):
    """outstation_model(...) as the file's text."""
    return outstation_model(*args, **kw).text()


def central_model(mdp_port, stations, host="127.0.0.1", comment="", retain=None, serial=None,
                  status_first=False, fc23=False, channel=False):
    """The central's plcrt config. serial: serial_keys(...) for an RTU link to the MDP-810 (the
    devices share the line); status_first: the read ranges read the status word alone until
    it shows new data (runtime_shim README, docs/serial.md)."""
    cfg = _config(comment, "plcrt config of the central (plc/central*.st): the MDP-810, one "
                  "device per\noutstation (unit id = station address).")
    _add_retain(cfg, retain)
    for s in range(1, stations + 1):
        cfg.add("device", f"mdp{s}", **_link(serial, host, mdp_port, fc23),
                unit_id=f"%QW{CHANNEL_UNIT}" if channel and s == 1 else s,
                errors=f"%IW{30 + s}", online=f"%IX9.{s}")
        _read_write_ranges(cfg, f"mdp{s}", s, MDP810.read_status, MDP810.write_data, status_first,
                           channel and s == 1)
    return cfg


def central_config(*args, **kw):
    """central_model(...) as the file's text."""
    return central_model(*args, **kw).text()


# The central of a large network (plc/central_many.st): one shared client, its statistics at
# %MW100..: the order of the members of PLC_T_ManyStats in plc/PLC_Logger.st (member k at
# STATS_BASE + k), read from the ST as the P_, R_ and S_ numbers above
MANY_WORDS = {_const_name(m): STATS_BASE + k for k, m in enumerate(stats_members())}
M_STATIONS, M_READS, M_READ_ERRS, M_WRITES, M_WRITE_ERRS, M_REC_LO, M_REC_HI, M_TRANSFERS, \
    M_FAILED, M_ERR_STATION, M_ROUNDS = (MANY_WORDS[n] for n in (
        "STATIONS", "READS", "READ_ERRS", "WRITES", "WRITE_ERRS", "REC_LO", "REC_HI",
        "TRANSFERS", "FAILED", "ERR_STATION", "ROUNDS"))


def central_many_config(mdp_port, host="127.0.0.1", comment="", retain=None):
    """plcrt config of plc/central_many.st: two devices on the MDP-810, one for the reads and
    one for the acknowledgement writes, each taking its unit id (the station) from the image
    at the trigger's rising edge; a read and a write may so start in the same scan."""
    cfg = _config(comment, "plcrt config of the central of a large network (plc/central_many.st)"
                  ": ONE\nModbus client for all stations; the program chooses the unit id per "
                  "request.")
    _add_retain(cfg, retain)
    cfg.add("device", "mdp", host=host, port=mdp_port, unit_id="%QW2", errors="%IW31",
            online="%IX9.1")
    cfg.add("device", "mdp_ack", host=host, port=mdp_port, unit_id="%QW3", errors="%IW32",
            online="%IX9.2")
    cfg.add("read", "mdp_read", device="mdp", start=MDP810.read_status, size=125, image="%IW100",
            policy="trigger", trigger="%QX1.0", done="%IX1.0", error="%IX1.1", status="%IW11")
    cfg.add("write", "mdp_write", device="mdp_ack", start=MDP810.write_data, size=123, image="%QW100",
            policy="trigger", trigger="%QX1.1", done="%IX1.2", error="%IX1.3", status="%IW21",
            length="%QW1")
    return cfg.text()


# the PLC-to-modem link of the demo and mip-cosim: "tcp" or "rtu:BAUD" (docs/serial.md)
RTU_BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)


def parse_link(text):
    """0 for "tcp", the baud rate for "rtu:BAUD"; ValueError with the one line to show."""
    if text == "tcp":
        return 0
    kind, _, baud = text.partition(":")
    if kind != "rtu" or not baud.isdigit() or int(baud) not in RTU_BAUDS:
        raise ValueError(f"--link must be tcp or rtu:BAUD with BAUD one of "
                         f"{', '.join(map(str, RTU_BAUDS))}, got {text!r}")
    return int(baud)
