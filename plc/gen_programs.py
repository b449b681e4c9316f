#!/usr/bin/env python3
"""Writes the example programs plc/{outstation,central}{,_bidi}.st, plc/central_many.st and the
OpenPLC v3 Modbus configurations plc/openplc/{outstation,central}-mbconfig.cfg.

Portable ST cannot index located variables, so the copies between the located Modbus image
and the MIP blocks' arrays are one statement per register; this script writes them with the
test kit's glue generator (kit/mipkit/glue.py, the integrators' `mip-glue`: one implementation).
Run it after changing the layout (plc/README.md, "Register layout"); the outputs are committed.

    .venv/bin/python plc/gen_programs.py [--openplc-stations N] [--many-stations N] [-o DIR]

--openplc-stations sets how many stations the central's OpenPLC configuration serves
(default 2). Stock OpenPLC's Modbus master holds at most 400 registers per direction
(plc/openplc_limits.py): with the 125-register read block that is 3 stations, and a larger
number is refused with one line before anything is written.
--many-stations sets how many receivers plc/central_many.st has (default 8; the co-simulation
and the benchmark generate it for up to 247 stations).
"""
import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from openplc_limits import MAX_MB_IO, LimitError, check as check_openplc  # noqa: E402


def _load_glue():
    """kit/mipkit/glue.py by its path: the generator alone (stdlib only), not the kit package
    with the co-simulation behind it."""
    import importlib.util
    name = "mipkit_glue_for_gen_programs"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE.parent / "kit" / "mipkit" / "glue.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod            # dataclasses look the module up while it loads
        spec.loader.exec_module(mod)
    return sys.modules[name]


glue = _load_glue()

OPENPLC_STATIONS = 2      # devices in the committed plc/openplc/central-mbconfig.cfg
MAX_STATIONS = 4          # receivers in the central programs (devices 1..4)
READ_REGS = 125           # one FC3 at the read-status register: status, count, 123 data
WRITE_REGS = 123          # one FC16 at the first write register
WINDOW = 160              # PLC_RecordStore.aWindow


# the located image of the example programs: station s reads %IW100 + 125(s-1).. and writes
# %QW100 + 123(s-1).. into/from rd<s> and <fb>.aWrite, through r<s>_<i> / w<s>_<i>
GLUE = glue.Layout(read_base=100, read_count=READ_REGS, write_base=100, write_count=WRITE_REGS,
                   stations=MAX_STATIONS, read_array="rd{s}", write_array="rcv{s}.aWrite",
                   numbered=True)     # write_array: the central's; io_after() passes each block's
glue.check(GLUE, "plcrt")          # 4 stations of 125 pass OpenPLC's 400: station 4 idles there
# plc/central_many.st: ONE read and ONE write range for all stations, r_<i> / w_<i>
GLUE_MANY = glue.Layout(read_base=100, read_count=READ_REGS, write_base=100, write_count=WRITE_REGS,
                        read_array="rd", write_array="aWr", read_prefix="r_", write_prefix="w_",
                        numbered=False)
glue.check(GLUE_MANY, "openplc")


def read_image(s):        # station s (1-based): %IW of its read block
    return GLUE.read_image(s)


def write_image(s):
    return GLUE.write_image(s)


def peer_base(s):         # %MW block of peer s: receiver 0..19, sender 20..39, window 40..199
    return 100 + 200 * (s - 1)


PARAMS = """\
  (* parameters (%MW0..%MW23), written by the demo, a test or an operator panel *)
  pStart AT %MW0 : WORD;          (* <> 0: run *)
  pTotalLo AT %MW1 : WORD;        (* records to log and read out (0: 5) *)
  pTotalHi AT %MW2 : WORD;
  pPerTransfer AT %MW3 : WORD;    (* records per transfer (0: all in one) *)
  pPayload AT %MW4 : WORD;        (* payload registers per record (0: 16) *)
  pSession AT %MW5 : WORD;        (* session number, part of the data *)
  pStation AT %MW6 : WORD;        (* outstation: its address (0: 1) *)
  pFlags AT %MW7 : WORD;          (* bit 0 polled, bit 1 static mode, bit 2 cyclic I/O (OpenPLC), bit 3 retain, bit 4 window 2, bit 5 hand-over (central, central_bidi) *)
  pLogPeriod AT %MW8 : WORD;      (* ms between logged records (0: all at once) *)
  pTimeout AT %MW9 : WORD;        (* ms, tTimeout of the blocks (0: 2000) *)
  pChunkSize AT %MW10 : WORD;     (* registers per write block incl. header (0: 123); static: the static size *)
  pTransferTimeout AT %MW11 : WORD; (* s, receivers' tTransferTimeout (0: never) *)
  pMaxRetries AT %MW12 : WORD;    (* sender's uMaxRetries (0: unlimited) *)
  pCyclicWrite AT %MW13 : WORD;   (* cyclic I/O: ms after which a write counts as done (0: the next scan) *)
  pStartLo AT %MW14 : WORD;       (* records already read out (resume after a restart) *)
  pStartHi AT %MW15 : WORD;
  (* the central's own streams (bidirectional): records already read out, per station *)
  pDownStart1Lo AT %MW16 : WORD;
  pDownStart1Hi AT %MW17 : WORD;
  pDownStart2Lo AT %MW18 : WORD;
  pDownStart2Hi AT %MW19 : WORD;
  pDownStart3Lo AT %MW20 : WORD;
  pDownStart3Hi AT %MW21 : WORD;
  pDownStart4Lo AT %MW22 : WORD;
  pDownStart4Hi AT %MW23 : WORD;
  (* the runtime's snapshot handshake (plcrt [retain] request / saved; flags bit 3) *)
  snapReq AT %QX8.0 : BOOL;       (* a snapshot at the end of this scan, please *)
  snapSaved AT %IW8 : WORD;       (* snapshots completed *)
"""

PARAM_VARS = """\
  xRun : BOOL;
  xPolled : BOOL;
  xStatic : BOOL;
  xCyclic : BOOL;
  xRetain : BOOL;
  uWindow : UINT;
  udiTotal : UDINT;
  uPerTransfer : UINT;
  uPayload : UINT;
  uChunkSize : UINT;
  tTimeout : TIME;
  tTransferTimeout : TIME;
  tLogPeriod : TIME;
  tCyclicWrite : TIME;
  udiStart : UDINT;
"""

def ms_to_time(word):
    """ST for a TIME of `word` milliseconds (a WORD, 0..65535) that matiec computes right.

    matiec's standard library multiplies a TIME by an integer n as (tv_sec * n) seconds plus
    (int)(tv_nsec * n) nanoseconds through a 32-bit int: `T#1ms * n` is wrong (negative) for
    n > 2147. So the TIME is built from whole seconds and the remaining milliseconds:
    `T#1s * (n / 1000)` has tv_nsec 0 (the int product is 0, exact for any n) and
    `T#1ms * (n MOD 1000)` stays at most 999,000,000 ns < 2**31. Right for all 0..65535 ms.
    (matiec's DINT_TO_TIME would take n as seconds, CODESYS's as milliseconds: not portable.)
    """
    return (f"T#1s * (WORD_TO_DINT({word}) / 1000) + T#1ms * (WORD_TO_DINT({word}) MOD 1000)")


def s_to_time(word):
    """ST for a TIME of `word` seconds (0..65535): T#1s has tv_nsec 0, exact under matiec."""
    return f"T#1s * WORD_TO_DINT({word})"


PARAM_CODE = """\
(* parameters; a started program keeps them *)
IF NOT xRun THEN
  udiTotal := WORD_TO_UDINT(pTotalLo) + WORD_TO_UDINT(pTotalHi) * 65536;
  IF udiTotal = 0 THEN udiTotal := 5; END_IF;
  uPerTransfer := WORD_TO_UINT(pPerTransfer);
  uPayload := WORD_TO_UINT(pPayload);
  IF uPayload = 0 THEN uPayload := 16; END_IF;
  uChunkSize := WORD_TO_UINT(pChunkSize);
  IF uChunkSize = 0 THEN uChunkSize := 123; END_IF;
  xPolled := (pFlags AND 16#0001) <> 0;
  xStatic := (pFlags AND 16#0002) <> 0;
  xCyclic := (pFlags AND 16#0004) <> 0;
  xRetain := (pFlags AND 16#0008) <> 0;   (* warm restarts: the blocks wait for snapshots *)
  uWindow := 1;
  IF (pFlags AND 16#0010) <> 0 THEN uWindow := 2; END_IF;   (* the pipelined sender (P27) *)
  (* every TIME from seconds and milliseconds: matiec gets T#1ms * n wrong above n = 2147 *)
  tTimeout := MS_TIMEOUT;
  IF pTimeout = 0 THEN tTimeout := T#2s; END_IF;
  tTransferTimeout := S_TRANSFER_TIMEOUT;
  tLogPeriod := MS_LOG_PERIOD;
  tCyclicWrite := MS_CYCLIC_WRITE;
  udiStart := WORD_TO_UDINT(pStartLo) + WORD_TO_UDINT(pStartHi) * 65536;
  xRun := pStart <> 0;
END_IF;
""".replace("MS_TIMEOUT", ms_to_time("pTimeout")).replace(
    "S_TRANSFER_TIMEOUT", s_to_time("pTransferTimeout")).replace(
    "MS_LOG_PERIOD", ms_to_time("pLogPeriod")).replace(
    "MS_CYCLIC_WRITE", ms_to_time("pCyclicWrite"))


def located_io(s, tag):
    """Declarations of station s's located I/O (see the runtime configs)."""
    lines = [
        f"  (* modem {tag}: read block %IW{read_image(s)}.., write block %QW{write_image(s)}.. *)",
        f"  rdTrig{s} AT %QX{s}.0 : BOOL;",
        f"  rdDone{s} AT %IX{s}.0 : BOOL;",
        f"  rdErr{s} AT %IX{s}.1 : BOOL;",
        f"  rdSt{s} AT %IW{10 + s} : WORD;         (* the read's status: why it failed *)",
        f"  wrTrig{s} AT %QX{s}.1 : BOOL;",
        f"  wrDone{s} AT %IX{s}.2 : BOOL;",
        f"  wrErr{s} AT %IX{s}.3 : BOOL;",
        f"  wrLen{s} AT %QW{s} : WORD;",
    ]
    lines += glue.declarations(GLUE, s)
    lines += [f"  rd{s} : MIP_T_ReadBlock;", f"  xRdValid{s} : BOOL;", f"  xWrDone{s} : BOOL;",
              f"  tonWr{s} : TON;"]
    return lines


def status_vars(s, receiver=True, sender=True):
    b = peer_base(s)
    out = []
    if receiver:
        names = ["Seq", "Flags", "Number", "Len", "Error", "RecLo", "RecHi", "ComLo", "ComHi",
                 "SumA", "SumB", "Transfers", "Failed", "Dup", "Unexp", "OpenLo", "OpenHi"]
        out += [f"  mR{s}{n} AT %MW{b + i} : WORD;" for i, n in enumerate(names)]
        out += [f"  mWin{s}_{i} AT %MW{b + 40 + i} : WORD;" for i in range(WINDOW)]
    if sender:
        names = ["Seq", "Flags", "Error", "LogLo", "LogHi", "OutLo", "OutHi", "Done", "Failed",
                 "Retrans", "All"]
        out += [f"  mS{s}{n} AT %MW{b + 20 + i} : WORD;" for i, n in enumerate(names)]
    return out


def io_before(s):
    """Read handshake and read block copy, before the MIP block is called."""
    lines = [f"(* station {s}: read handshake (trigger policy): a read every other scan; the block is"
             f" copied when it is valid (the MIP blocks look at aRead only with xReadValid) *)",
             f"xRdValid{s} := rdDone{s} OR xCyclic;",
             f"IF xRdValid{s} THEN"]
    lines += glue.read_copies(GLUE, s)
    lines += [
        "END_IF;",
        f"rdTrig{s} := xRun AND NOT (rdDone{s} OR rdErr{s});",
        f"tonWr{s}(IN := xCyclic AND wrTrig{s}, PT := tCyclicWrite);",
        f"xWrDone{s} := wrDone{s} OR tonWr{s}.Q;",
    ]
    return lines


def io_after(s, fb):
    lines = [f"(* station {s}: write handshake and block; the runtime takes the block at the"
             f" request's rising edge, OpenPLC's cyclic master whenever it polls *)",
             f"wrTrig{s} := {fb}.xWriteReq;",
             f"IF wrTrig{s} OR xCyclic THEN",
             f"  wrLen{s} := UINT_TO_WORD({fb}.uWriteLen);"]
    lines += glue.write_copies(GLUE, s, array=f"{fb}.aWrite")
    lines += ["END_IF;"]
    return lines


def store_out(s, store, extra_failed=None):
    lines = [
        f"mR{s}Seq := {store}.wSeq;", f"mR{s}Flags := {store}.wFlags;",
        f"mR{s}Number := {store}.wNumber;", f"mR{s}Len := {store}.wLen;",
        f"mR{s}Error := {store}.wError;",
        f"mR{s}RecLo := UDINT_TO_WORD({store}.udiRecords MOD 65536);",
        f"mR{s}RecHi := UDINT_TO_WORD({store}.udiRecords / 65536);",
        f"mR{s}ComLo := UDINT_TO_WORD({store}.udiCommitted MOD 65536);",
        f"mR{s}ComHi := UDINT_TO_WORD({store}.udiCommitted / 65536);",
        f"mR{s}SumA := {store}.wSumA;", f"mR{s}SumB := {store}.wSumB;",
        f"mR{s}Transfers := UINT_TO_WORD({store}.uTransfers);",
        f"mR{s}Failed := UINT_TO_WORD({store}.uFailed);",
        f"mR{s}OpenLo := UDINT_TO_WORD({store}.udiOpen MOD 65536);",
        f"mR{s}OpenHi := UDINT_TO_WORD({store}.udiOpen / 65536);",
    ]
    lines += [f"mWin{s}_{i} := {store}.aWindow[{i}];" for i in range(WINDOW)]
    return lines


def source_out(s, src, retrans):
    return [
        f"mS{s}Seq := {src}.wSeq;", f"mS{s}Flags := {src}.wFlags;",
        f"mS{s}Error := {src}.wLastError;",
        f"mS{s}LogLo := UDINT_TO_WORD({src}.udiLogged MOD 65536);",
        f"mS{s}LogHi := UDINT_TO_WORD({src}.udiLogged / 65536);",
        f"mS{s}OutLo := UDINT_TO_WORD({src}.udiReadOut MOD 65536);",
        f"mS{s}OutHi := UDINT_TO_WORD({src}.udiReadOut / 65536);",
        f"mS{s}Done := UINT_TO_WORD({src}.uTransfersDone);",
        f"mS{s}Failed := UINT_TO_WORD({src}.uTransfersFailed);",
        f"mS{s}Retrans := UDINT_TO_WORD({retrans} MOD 65536);",
        f"IF {src}.xAllReadOut THEN mS{s}All := WORD#1; ELSE mS{s}All := WORD#0; END_IF;",
    ]


def var_blocks(decl):
    """Located and unlocated variables in separate VAR blocks (matiec wants that). The
    unlocated ones are RETAIN: the blocks, the logger and the store with the parameters they
    run with, so that a warm start resumes where the last snapshot was (st_lib/PROTOCOL.md
    W3); without retain in the runtime (or on OpenPLC, which ignores RETAIN) nothing changes."""
    lines = "\n".join(decl).split("\n")
    located = [l for l in lines if " AT %" in l]
    plain = [l for l in lines if " AT %" not in l and l.strip()]
    return ("VAR RETAIN\n" + "\n".join(plain) + "\nEND_VAR\nVAR\n" + "\n".join(located)
            + "\nEND_VAR\n")


def config(prog, inst):
    return (f"\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            f"    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);\n"
            f"    PROGRAM {inst} WITH tMain : {prog};\n  END_RESOURCE\nEND_CONFIGURATION\n")


HEADER = "(* GENERATED by plc/gen_programs.py -- edit the generator, not this file.\n{doc} *)\n"


def outstation(bidi):
    prog = "OutstationBidi" if bidi else "Outstation"
    fb = "link" if bidi else "snd"
    decl = [PARAMS, PARAM_VARS, "  src : PLC_LogSource;"]
    decl.append("  link : MIP_Link;" if bidi else "  snd : MIP_Sender;")
    if bidi:
        decl += ["  store : PLC_RecordStore;"]
    decl += located_io(1, "TRM-810")
    decl += status_vars(1, receiver=bidi, sender=True)
    code = [PARAM_CODE]
    code += io_before(1)
    code.append("(* the logger: station pStation, records 1..udiTotal *)")
    code.append(f"src(xRun := xRun, udiTotal := udiTotal, uPerTransfer := uPerTransfer, "
                f"uPayload := uPayload,\n    wSession := pSession, wStation := pStation, "
                f"tLogPeriod := tLogPeriod, udiStart := udiStart,\n"
                + (f"    xChunkRequest := link.xChunkRequest, udiChunkIndex := link.udiChunkIndex, "
                   f"uChunkMax := link.uChunkMax,\n    xSendDone := link.xSendDone, "
                   f"xSendError := link.xSendError, eSendError := link.eSendErrorId);"
                   if bidi else
                   f"    xChunkRequest := snd.xChunkRequest, udiChunkIndex := snd.udiChunkIndex, "
                   f"uChunkMax := snd.uChunkMax,\n    xSendDone := snd.xDone, "
                   f"xSendError := snd.xError, eSendError := snd.eErrorId);"))
    if bidi:
        code.append(
            "link(xEnable := xRun, xExecute := src.xExecute, xCentral := FALSE, xPolled := xPolled,\n"
            "     xStatic := xStatic, uChunkSize := uChunkSize, tTimeout := tTimeout,\n"
            "     uMaxRetries := WORD_TO_UINT(pMaxRetries), uWindow := uWindow,\n"
            "     tTransferTimeout := tTransferTimeout,\n"
            "     xChunkValid := src.xChunkValid, aChunk := src.aChunk, uChunkLen := src.uChunkLen,\n"
            "     xChunkLast := src.xChunkLast, aRead := rd1, xReadValid := xRdValid1,\n"
            "     xReadError := rdErr1, wReadStatus := rdSt1,\n"
            "     xWriteDone := xWrDone1, xWriteError := wrErr1, xRetained := xRetain,\n"
            "     wSnapshots := snapSaved);")
        code.append("store(xRecordValid := link.xRecordValid, aRecord := link.aRecord,\n"
                    "      uRecordLen := link.uRecordLen, wRecordNumber := link.wRecordNumber,\n"
                    "      xTransferEnd := link.xRecvTransferEnd,\n"
                    "      udiFailed := link.udiFailedTransfers, eLastError := link.eRecvErrorId);")
        code += store_out(1, "store")
        code.append("mR1Dup := UDINT_TO_WORD(link.udiDuplicates MOD 65536);")
        code.append("mR1Unexp := UDINT_TO_WORD(link.udiUnexpected MOD 65536);")
        code += source_out(1, "src", "link.udiRetransmissions")
        code.append("snapReq := link.xSnapshotReq;")
    else:
        code.append(
            "snd(xExecute := src.xExecute, uChunkSize := uChunkSize, xPolled := xPolled,\n"
            "    xStatic := xStatic, tTimeout := tTimeout, uMaxRetries := WORD_TO_UINT(pMaxRetries),\n"
            "    uWindow := uWindow,\n"
            "    xChunkValid := src.xChunkValid, aChunk := src.aChunk, uChunkLen := src.uChunkLen,\n"
            "    xChunkLast := src.xChunkLast, xWriteDone := xWrDone1, xWriteError := wrErr1,\n"
            "    aRead := rd1, xReadValid := xRdValid1, xReadError := rdErr1, wReadStatus := rdSt1,\n"
            "    xRetained := xRetain, wSnapshots := snapSaved);")
        code.append("snapReq := snd.xSnapshotReq;")
        code += source_out(1, "src", "snd.udiRetransmissions")
    code += io_after(1, fb)
    doc = ("    The outstation: a data logger read out over the TRM-810 "
           + ("with MIP_Link (both directions: it also receives and stores the central's stream)."
              if bidi else "with MIP_Sender."))
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n" + var_blocks(decl) + "\n".join(code) + "\nEND_PROGRAM\n" + config(prog, "out0"))


HANDOVER_VARS = """\
  xHandOver : BOOL;   (* flags bit 5: a record is acknowledged only once the control system took it *)
"""

HANDOVER_CODE = """\
(* flags bit 5, sampled with the other parameters (before xRun is set): the hand-over to the
   control system (PLC_HandOver) before the acknowledgement *)
IF NOT xRun THEN
  xHandOver := (pFlags AND 16#0020) <> 0;
END_IF;
"""


def handover_vars(s):
    """The hand-over registers of station s (B+17, B+18) and its PLC_HandOver."""
    b = peer_base(s)
    return [f"  ho{s} : PLC_HandOver;",
            f"  mR{s}Offered AT %MW{b + 17} : WORD;   (* records offered to the control system (hand-over) *)",
            f"  mR{s}Taken AT %MW{b + 18} : WORD;     (* the control system writes the offered number back once it took the record *)"]


def central(bidi):
    prog = "CentralBidi" if bidi else "Central"
    decl = [PARAMS, PARAM_VARS, HANDOVER_VARS]
    code = [HANDOVER_CODE, PARAM_CODE]
    for s in range(1, MAX_STATIONS + 1):
        decl.append(f"  (* ---- station {s} (MDP-810 unit id {s}) *)")
        decl.append(f"  store{s} : PLC_RecordStore;")
        if bidi:
            decl += [f"  link{s} : MIP_Link;", f"  src{s} : PLC_LogSource;"]
        else:
            decl.append(f"  rcv{s} : MIP_Receiver;")
        decl += handover_vars(s)
        decl += located_io(s, f"MDP-810 unit {s}")
        decl += status_vars(s, receiver=True, sender=bidi)
        code += io_before(s)
        if bidi:
            code.append(
                f"(* the central's own stream to station {s}: session pSession + 16#8000 *)\n"
                f"src{s}(xRun := xRun, udiTotal := udiTotal, uPerTransfer := uPerTransfer, "
                f"uPayload := uPayload,\n    wSession := pSession XOR 16#8000, wStation := WORD#{s}, "
                f"tLogPeriod := tLogPeriod,\n    udiStart := WORD_TO_UDINT(pDownStart{s}Lo) + "
                f"WORD_TO_UDINT(pDownStart{s}Hi) * 65536,\n"
                f"    xChunkRequest := link{s}.xChunkRequest, udiChunkIndex := link{s}.udiChunkIndex,"
                f" uChunkMax := link{s}.uChunkMax,\n    xSendDone := link{s}.xSendDone, "
                f"xSendError := link{s}.xSendError, eSendError := link{s}.eSendErrorId);")
            code.append(
                f"link{s}(xEnable := xRun, xExecute := src{s}.xExecute, xCentral := TRUE, "
                f"xPolled := xPolled,\n     xStatic := xStatic, uChunkSize := uChunkSize, "
                f"tTimeout := tTimeout,\n     uMaxRetries := WORD_TO_UINT(pMaxRetries), "
                f"uWindow := uWindow,\n     tTransferTimeout := tTransferTimeout,\n"
                f"     xChunkValid := src{s}.xChunkValid, "
                f"aChunk := src{s}.aChunk, uChunkLen := src{s}.uChunkLen,\n"
                f"     xChunkLast := src{s}.xChunkLast, aRead := rd{s}, xReadValid := xRdValid{s},\n"
                f"     xReadError := rdErr{s}, wReadStatus := rdSt{s},\n"
                f"     xWriteDone := xWrDone{s}, xWriteError := wrErr{s}, xRetained := xRetain,\n"
                f"     wSnapshots := snapSaved, xAckByCaller := xHandOver,\n"
                f"     xRecordProcessed := ho{s}.xProcessed);")
            code.append(f"ho{s}(xWait := xHandOver, xRecordValid := link{s}.xRecordValid, wTaken := mR{s}Taken);")
            code.append(f"store{s}(xRecordValid := ho{s}.xStore, aRecord := link{s}.aRecord,\n"
                        f"      uRecordLen := link{s}.uRecordLen, wRecordNumber := link{s}.wRecordNumber,\n"
                        f"      xTransferEnd := link{s}.xRecvTransferEnd,\n"
                        f"      udiFailed := link{s}.udiFailedTransfers, eLastError := link{s}.eRecvErrorId);")
            code += store_out(s, f"store{s}")
            code.append(f"mR{s}Offered := ho{s}.wOffered;")
            code.append(f"mR{s}Dup := UDINT_TO_WORD(link{s}.udiDuplicates MOD 65536);")
            code.append(f"mR{s}Unexp := UDINT_TO_WORD(link{s}.udiUnexpected MOD 65536);")
            code += source_out(s, f"src{s}", f"link{s}.udiRetransmissions")
            code += io_after(s, f"link{s}")
        else:
            code.append(
                f"rcv{s}(xEnable := xRun, xPolled := xPolled, xStatic := xStatic, tTimeout := tTimeout,\n"
                f"     tTransferTimeout := tTransferTimeout, aRead := rd{s}, xReadValid := xRdValid{s},\n"
                f"     xReadError := rdErr{s}, wReadStatus := rdSt{s},\n"
                f"     xWriteDone := xWrDone{s}, xWriteError := wrErr{s}, xRetained := xRetain,\n"
                f"     wSnapshots := snapSaved, xAckByCaller := xHandOver,\n"
                f"     xRecordProcessed := ho{s}.xProcessed);")
            code.append(f"ho{s}(xWait := xHandOver, xRecordValid := rcv{s}.xRecordValid, wTaken := mR{s}Taken);")
            code.append(f"store{s}(xRecordValid := ho{s}.xStore, aRecord := rcv{s}.aRecord,\n"
                        f"      uRecordLen := rcv{s}.uRecordLen, wRecordNumber := rcv{s}.wRecordNumber,\n"
                        f"      xTransferEnd := rcv{s}.xTransferEnd,\n"
                        f"      udiFailed := rcv{s}.udiFailedTransfers, eLastError := rcv{s}.eLastErrorId);")
            code += store_out(s, f"store{s}")
            code.append(f"mR{s}Offered := ho{s}.wOffered;")
            code.append(f"mR{s}Dup := UDINT_TO_WORD(rcv{s}.udiDuplicates MOD 65536);")
            code.append(f"mR{s}Unexp := UDINT_TO_WORD(rcv{s}.udiUnexpected MOD 65536);")
            code += io_after(s, f"rcv{s}")
    fb = "link" if bidi else "rcv"
    code.append("snapReq := " + " OR ".join(f"{fb}{s}.xSnapshotReq" for s in range(1, MAX_STATIONS + 1)) + ";")
    doc = (f"    The central: one {'MIP_Link' if bidi else 'MIP_Receiver'} per outstation "
           f"(MDP-810 unit ids 1..{MAX_STATIONS}),\n    each with a PLC_RecordStore"
           + (" and a logger of its own sent down to the station." if bidi else ".")
           + "\n    Flags bit 5: a record is acknowledged only once the control system took it"
             " (PLC_HandOver,\n    %MW B+17 offered, B+18 taken), so a cold restart after the"
             " acknowledgement loses nothing.")
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n" + var_blocks(decl) + "\n".join(code) + "\nEND_PROGRAM\n" + config(prog, "cen0"))


MANY_STATIONS = 8         # receivers in the committed plc/central_many.st (any 1..247 generated)
MAX_UNIT = 247            # Modbus unit ids 1..247: the largest MIP network behind one MDP-810


def central_many(n):
    """The central for a large network: n receivers (n <= 247) behind ONE shared Modbus client.

    plc/central.st gives every station its own read and write range (an own Modbus client per
    station, as stock OpenPLC needs it); 247 of them would not fit any PLC's I/O image. Here
    one read range and one write range serve all stations: the program puts the station's
    unit id into %QW2 (read) / %QW3 (write) before it raises the trigger, and the runtime
    takes the unit id with the request (plcrt `unit_id = %QWn`; CODESYS/TwinCAT Modbus client
    blocks take it as an input the same way). Reads go round robin over the stations; a
    receiver that asks for a write (its acknowledgement) is served by the write range, in
    turn. Each receiver is called every scan (its timers run); aRead is passed only to the one
    whose read completed, so an idle scan copies no blocks. Matiec has no arrays of function
    blocks, so the instances are named rcv1..rcvN and this generator writes the per-station
    lines."""
    if not 1 <= n <= MAX_UNIT:
        raise ValueError(f"stations {n}: 1..{MAX_UNIT}")
    prog = "CentralMany"
    decl = [PARAMS, PARAM_VARS, f"""\
  (* the shared Modbus client: read range %IW100.. (trigger %QX1.0), write range %QW100.. *)
  (* (trigger %QX1.1); each takes its unit id from the image at the trigger's rising edge *)
  rdTrig AT %QX1.0 : BOOL;
  rdDone AT %IX1.0 : BOOL;
  rdErr AT %IX1.1 : BOOL;
  wrTrig AT %QX1.1 : BOOL;
  wrDone AT %IX1.2 : BOOL;
  wrErr AT %IX1.3 : BOOL;
  wrLen AT %QW1 : WORD;
  rdUnit AT %QW2 : WORD;          (* unit id (= station) of the next read *)
  wrUnit AT %QW3 : WORD;          (* unit id of the next write *)
  (* statistics for an operator panel or a test *)
  mStations AT %MW100 : WORD;     (* receivers in this program *)
  mReads AT %MW101 : WORD;        (* reads completed (mod 65536) *)
  mReadErrs AT %MW102 : WORD;     (* reads failed *)
  mWrites AT %MW103 : WORD;       (* acknowledgement writes completed *)
  mWriteErrs AT %MW104 : WORD;    (* writes failed *)
  mRecLo AT %MW105 : WORD;        (* records delivered, all stations *)
  mRecHi AT %MW106 : WORD;
  mTransfers AT %MW107 : WORD;    (* transfers completed, all stations *)
  mFailed AT %MW108 : WORD;       (* transfers failed, all stations *)
  mErrStation AT %MW109 : WORD;   (* the last station whose transfer failed (0: none) *)
  mRound AT %MW110 : WORD;        (* read rounds over all stations completed *)
  uStations : UINT := {n};
  uRdNext : UINT := 1;            (* round robin: the station read next *)
  uRdSt : UINT;                   (* station of the read in progress *)
  uRdDone : UINT;                 (* this scan: the station whose read completed (0: none) *)
  xRdOk : BOOL;
  xRdIdle : BOOL;
  uWrNext : UINT := 1;            (* round robin: the first station asked for a write *)
  uWrSt : UINT;
  uWrDone : UINT;
  xWrOk : BOOL;
  xWrBad : BOOL;
  xWrIdle : BOOL;
  axWrReq : ARRAY[1..{n}] OF BOOL; (* rcvK.xWriteReq of this scan *)
  rd : MIP_T_ReadBlock;
  aWr : MIP_T_Block;
  uWrLen : UINT;
  uI : UINT;
  uK : UINT;
  udiRecords : UDINT;
  uReads : UINT;
  uReadErrs : UINT;
  uWrites : UINT;
  uWriteErrs : UINT;
  uTransfers : UINT;
  uFailed : UINT;
  uRounds : UINT;"""]
    decl += glue.declarations(GLUE_MANY, 1)
    for s in range(1, n + 1):
        decl += [f"  rcv{s} : MIP_Receiver;", f"  store{s} : PLC_RecordStore;"]
    code = [PARAM_CODE, """\
(* 1. the shared client: which request completed (the trigger is dropped for one scan) *)
uRdDone := 0;
uWrDone := 0;
xRdOk := FALSE;
xWrOk := FALSE;
xWrBad := FALSE;
xRdIdle := NOT rdTrig;
xWrIdle := NOT wrTrig;
IF rdTrig AND (rdDone OR rdErr) THEN
  IF rdDone THEN"""]
    code += glue.read_copies(GLUE_MANY, 1, indent="    ")
    code += ["""\
    xRdOk := TRUE;
    uReads := uReads + 1;
  ELSE
    uReadErrs := uReadErrs + 1;
  END_IF;
  uRdDone := uRdSt;
  rdTrig := FALSE;
END_IF;
IF wrTrig AND (wrDone OR wrErr) THEN
  xWrOk := wrDone;
  xWrBad := NOT wrDone;
  IF wrDone THEN uWrites := uWrites + 1; ELSE uWriteErrs := uWriteErrs + 1; END_IF;
  uWrDone := uWrSt;
  wrTrig := FALSE;
END_IF;
(* 2. every receiver, every scan; the one whose read completed gets the block *)"""]
    for s in range(1, n + 1):
        common = (f"xEnable := xRun, xPolled := xPolled, xStatic := xStatic, tTimeout := tTimeout,\n"
                  f"       tTransferTimeout := tTransferTimeout,\n"
                  f"       xWriteDone := xWrOk AND uWrDone = {s}, "
                  f"xWriteError := xWrBad AND uWrDone = {s}")
        code += [f"IF uRdDone = {s} THEN",
                 f"  rcv{s}({common},\n       aRead := rd, xReadValid := xRdOk);",
                 "ELSE",
                 f"  rcv{s}({common},\n       xReadValid := FALSE);",
                 "END_IF;",
                 f"IF rcv{s}.xRecordValid OR rcv{s}.xTransferEnd OR rcv{s}.xError THEN",
                 f"  store{s}(xRecordValid := rcv{s}.xRecordValid, aRecord := rcv{s}.aRecord,\n"
                 f"         uRecordLen := rcv{s}.uRecordLen, wRecordNumber := rcv{s}.wRecordNumber,\n"
                 f"         xTransferEnd := rcv{s}.xTransferEnd,\n"
                 f"         udiFailed := rcv{s}.udiFailedTransfers, eLastError := rcv{s}.eLastErrorId);",
                 f"  IF rcv{s}.xRecordValid THEN udiRecords := udiRecords + 1; END_IF;",
                 f"  IF rcv{s}.xTransferEnd THEN uTransfers := uTransfers + 1; END_IF;",
                 f"  IF (store{s}.wFlags AND 2) <> 0 THEN uFailed := uFailed + 1; mErrStation := WORD#{s}; END_IF;",
                 "END_IF;",
                 f"axWrReq[{s}] := rcv{s}.xWriteReq;"]
    code += [f"""\
snapReq := FALSE;   (* not RETAIN: no snapshots wanted *)
(* 3. start requests: the next write asked for (round robin), the next station's read *)
IF xRun AND xWrIdle THEN
  uK := 0;
  uI := 0;
  WHILE uI < uStations DO   (* not FOR uI := 1 TO uStations: upstream matiec runs that zero times for one station *)
    uI := uI + 1;
    IF axWrReq[uWrNext] THEN
      uK := uWrNext;
    END_IF;
    uWrNext := uWrNext MOD uStations + 1;
    IF uK <> 0 THEN
      EXIT;
    END_IF;
  END_WHILE;
  IF uK <> 0 THEN
    CASE uK OF"""]
    code += [f"      {s}: aWr := rcv{s}.aWrite; uWrLen := rcv{s}.uWriteLen;" for s in range(1, n + 1)]
    code += ["    END_CASE;"]
    code += glue.write_copies(GLUE_MANY, 1, indent="    ")
    code += ["""\
    wrLen := UINT_TO_WORD(uWrLen);
    wrUnit := UINT_TO_WORD(uK);
    uWrSt := uK;
    wrTrig := TRUE;
  END_IF;
END_IF;
IF xRun AND xRdIdle THEN
  rdUnit := UINT_TO_WORD(uRdNext);
  uRdSt := uRdNext;
  rdTrig := TRUE;
  IF uRdNext = uStations THEN uRounds := uRounds + 1; END_IF;
  uRdNext := uRdNext MOD uStations + 1;
END_IF;
(* 4. statistics *)
mStations := UINT_TO_WORD(uStations);
mReads := UINT_TO_WORD(uReads);
mReadErrs := UINT_TO_WORD(uReadErrs);
mWrites := UINT_TO_WORD(uWrites);
mWriteErrs := UINT_TO_WORD(uWriteErrs);
mRecLo := UDINT_TO_WORD(udiRecords MOD 65536);
mRecHi := UDINT_TO_WORD(udiRecords / 65536);
mTransfers := UINT_TO_WORD(uTransfers);
mFailed := UINT_TO_WORD(uFailed);
mRound := UINT_TO_WORD(uRounds);"""]
    doc = (f"    The central of a large network: {n} MIP_Receivers (MDP-810 unit ids 1..{n}) behind\n"
           f"    one shared Modbus client (plcrt: unit id from %QW2 / %QW3); see central_many() in\n"
           f"    plc/gen_programs.py. Not RETAIN: warm restarts of this program are not covered.")
    # not RETAIN (unlike the other examples): warm restarts of this program are not covered
    # yet; stc's retain table and symbol table grow with every member of 2 x 247 instances
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n"
            + var_blocks(decl).replace("VAR RETAIN\n", "VAR\n", 1) + "\n".join(code)
            + "\nEND_PROGRAM\n" + config(prog, "cen0"))


# ---------------------------------------------------------------- the chain (issue 35)
# relay -> outstation (MIP_SoeReader -> PLC_SoeLog -> MIP_Sender) -> radio -> central
# (MIP_Receiver, xAckByCaller -> PLC_SoeHandOver -> MIP_SoeServer) -> a polling SCADA.
SOE_REGS = 26             # 40601..40626: count, SOE_Control, 3 message blocks of 8
SOE_READ_IMAGE = 300      # the outstation reads the relay's 26 registers into %IW300..
SOE_WRITE_IMAGE = 300     # and writes SOE_Control from %QW300
SOE_SERVER_IMAGE = 600    # the central serves them at %QW600.. (holding 600.., the relay's)

SOE_PARAMS = """\
  (* parameters (%MW0..%MW7), written by the demo, a test or an operator panel *)
  pStart AT %MW0 : WORD;          (* <> 0: run *)
  pPerRecord AT %MW1 : WORD;      (* outstation: relay entries per record (0: 15, at most 15) *)
  pPerTransfer AT %MW2 : WORD;    (* outstation: records per transfer (0: 1) *)
  pFlags AT %MW3 : WORD;          (* bit 0: warm restarts (the blocks' xRetained); bit 1: central (pull) acknowledges a record once its entries are queued, not after the SCADA took them (a measurement only); bit 2: central (push) a redundant pair of drivers; bit 3: central (push) driver B is the active one, read every scan *)
  pTimeout AT %MW4 : WORD;        (* ms, tTimeout of the MIP blocks (0: 2000) *)
  pMaxRetries AT %MW5 : WORD;     (* outstation: MIP_Sender's uMaxRetries (0: unlimited) *)
  pAckTimeout AT %MW6 : WORD;     (* central: s without the SCADA's acknowledgement until MIP_SoeServer reports it silent (0: never) *)
  (* the runtime's snapshot handshake (plcrt [retain] request / saved; flags bit 0) *)
  snapReq AT %QX8.0 : BOOL;       (* a snapshot at the end of this scan, please *)
  snapSaved AT %IW8 : WORD;       (* snapshots completed *)
"""

SOE_PARAM_VARS = """\
  xRun : BOOL;                    (* started: the parameters below are taken *)
  xRetain : BOOL;                 (* flags bit 0 *)
  xAckOnReceipt : BOOL;           (* flags bit 1 *)
  tTimeout : TIME;                (* pTimeout *)
  uPerRecord : UINT;              (* pPerRecord *)
  uPerTransfer : UINT;            (* pPerTransfer *)
"""

SOE_PARAM_CODE = """\
(* parameters; a started program keeps them *)
IF NOT xRun THEN
  xRetain := (pFlags AND 16#0001) <> 0;
  xAckOnReceipt := (pFlags AND 16#0002) <> 0;
  tTimeout := MS_TIMEOUT;
  IF pTimeout = 0 THEN tTimeout := T#2s; END_IF;
  uPerRecord := WORD_TO_UINT(pPerRecord);
  IF uPerRecord = 0 THEN uPerRecord := 15; END_IF;
  uPerTransfer := WORD_TO_UINT(pPerTransfer);
  IF uPerTransfer = 0 THEN uPerTransfer := 1; END_IF;
  xRun := pStart <> 0;
END_IF;
""".replace("MS_TIMEOUT", ms_to_time("pTimeout"))


def soe_status(names):
    """Status words %MW100.. for the demo, the co-simulation and an operator panel."""
    return [f"  {n} AT %MW{100 + i} : WORD;{' ' * max(1, 16 - len(n))}(* {c} *)"
            for i, (n, c) in enumerate(names)]


def udint_words(lo, hi, expr):
    return [f"{lo} := UDINT_TO_WORD({expr} MOD 65536);", f"{hi} := UDINT_TO_WORD({expr} / 65536);"]


def soe_io_before():
    """io_before(1) without OpenPLC's cyclic I/O (the chain runs on plcrt's trigger policy)."""
    lines = [c.replace(" OR xCyclic", "") for c in io_before(1) if not c.startswith("tonWr1(")]
    return [c.replace(" OR tonWr1.Q", "") for c in lines]


def soe_located_io(tag):
    """located_io(1) without the cyclic I/O's timer; the central's write block is rcv's."""
    return [l.replace("rcv1.aWrite", "rcv.aWrite") for l in located_io(1, tag) if "tonWr1" not in l]


def outstation_soe():
    prog = "OutstationSoe"
    decl = [SOE_PARAMS, SOE_PARAM_VARS,
            "  rdr : MIP_SoeReader;          (* the relay's event recorder *)",
            "  lgr : PLC_SoeLog;             (* stores its entries, feeds the sender *)",
            "  snd : MIP_Sender;             (* the MIP link to the central *)",
            "  aSoe : MIP_T_SoeRegs;         (* the relay's 26 registers as read *)"]
    decl += soe_located_io("TRM-810")
    decl += [f"  (* relay: 40601..40626 read into %IW{SOE_READ_IMAGE}.., SOE_Control written from %QW{SOE_WRITE_IMAGE} *)",
             "  soeRdTrig AT %QX2.0 : BOOL;     (* read trigger *)",
             "  soeRdDone AT %IX2.0 : BOOL;     (* read done *)",
             "  soeRdErr AT %IX2.1 : BOOL;      (* read failed *)",
             "  soeRdSt AT %IW12 : WORD;        (* the read's status: why it failed *)",
             "  soeWrTrig AT %QX2.1 : BOOL;     (* write trigger *)",
             "  soeWrDone AT %IX2.2 : BOOL;     (* write done *)",
             "  soeWrErr AT %IX2.3 : BOOL;      (* write failed *)",
             "  soeWrLen AT %QW2 : WORD;        (* registers written (1) *)",
             f"  soeWrVal AT %QW{SOE_WRITE_IMAGE} : WORD;     (* SOE_Control to write *)"]
    decl += [f"  soe{i} AT %IW{SOE_READ_IMAGE + i} : WORD;" for i in range(SOE_REGS)]
    decl += soe_status([("mStoredLo", "entries stored, low word"), ("mStoredHi", "high word"),
                        ("mSentLo", "entries read out (transfer done), low word"), ("mSentHi", "high word"),
                        ("mLevel", "entries in the logger"), ("mDone", "transfers done"),
                        ("mFailed", "transfers failed"), ("mError", "last failed transfer's error"),
                        ("mFlags", "bit 0 reader error, bit 1 reader caught up, bit 2 logger full, bit 3 sender error"),
                        ("mRetrans", "sender's retransmissions (mod 65536)")])
    code = [SOE_PARAM_CODE, "(* the relay: free-running reads of 40601..40626 (st_lib/README.md \"Wiring\") *)",
            "IF soeRdDone THEN"]
    code += [f"  aSoe[{i}] := soe{i};" for i in range(SOE_REGS)]
    code += ["END_IF;",
             "rdr(xEnable := xRun, xLoggerFull := lgr.xFull, xEntryStored := lgr.xEntryStored,",
             "    aRead := aSoe, xReadValid := soeRdDone, xReadError := soeRdErr, wReadStatus := soeRdSt,",
             "    xWriteDone := soeWrDone, xWriteError := soeWrErr, xRetained := xRetain,",
             "    xStoredPulse := TRUE, wSnapshots := snapSaved);",
             "soeRdTrig := xRun AND NOT (soeRdDone OR soeRdErr);",
             "soeWrTrig := rdr.xWriteReq;",
             "soeWrLen := WORD#1;",
             "soeWrVal := rdr.wWriteValue;"]
    code += soe_io_before()
    code += ["(* the logger: stores the entry the reader shows, sends records of whole entries *)",
             "lgr(xRun := xRun, uPerRecord := uPerRecord, uPerTransfer := uPerTransfer,",
             "    xEntryValid := rdr.xEntryValid, wTypeBit := rdr.wTypeBit, wAddress := rdr.wAddress,",
             "    wCauseType := rdr.wCauseType, wValue := rdr.wValue, wTime0 := rdr.wTime0,",
             "    wTime1 := rdr.wTime1, wTime2 := rdr.wTime2, wTime3 := rdr.wTime3,",
             "    xChunkRequest := snd.xChunkRequest, udiChunkIndex := snd.udiChunkIndex,",
             "    uChunkMax := snd.uChunkMax, xSendDone := snd.xDone, xSendError := snd.xError,",
             "    eSendError := snd.eErrorId, udiAcked := snd.udiRecords);",
             "snd(xExecute := lgr.xExecute, tTimeout := tTimeout, uMaxRetries := WORD_TO_UINT(pMaxRetries),",
             "    xChunkValid := lgr.xChunkValid, aChunk := lgr.aChunk, uChunkLen := lgr.uChunkLen,",
             "    xChunkLast := lgr.xChunkLast, xWriteDone := xWrDone1, xWriteError := wrErr1,",
             "    aRead := rd1, xReadValid := xRdValid1, xReadError := rdErr1, wReadStatus := rdSt1,",
             "    xRetained := xRetain, wSnapshots := snapSaved,",
             "    uWindow := 2);   (* pipelined (P27): the next record travels while the central hands one over *)",
             "snapReq := rdr.xSnapshotReq OR snd.xSnapshotReq;"]
    code += udint_words("mStoredLo", "mStoredHi", "lgr.udiStored")
    code += udint_words("mSentLo", "mSentHi", "lgr.udiSent")
    code += ["mLevel := UINT_TO_WORD(lgr.uLevel);", "mDone := UINT_TO_WORD(lgr.uTransfersDone);",
             "mFailed := UINT_TO_WORD(lgr.uTransfersFailed);", "mError := lgr.wLastError;",
             "mFlags := WORD#0;",
             "IF rdr.xError THEN mFlags := mFlags OR WORD#1; END_IF;",
             "IF rdr.xDone THEN mFlags := mFlags OR WORD#2; END_IF;",
             "IF lgr.xFull THEN mFlags := mFlags OR WORD#4; END_IF;",
             "IF snd.xError THEN mFlags := mFlags OR WORD#8; END_IF;",
             "mRetrans := UDINT_TO_WORD(snd.udiRetransmissions MOD 65536);"]
    code += [c.replace(" OR xCyclic", "") for c in io_after(1, "snd")]
    doc = ("    The chain's outstation (issue 35): MIP_SoeReader reads the relay's event recorder,\n"
           "    PLC_SoeLog stores its entries and MIP_Sender sends them to the central, records of\n"
           "    whole entries (8 registers each); the relay deletes an entry only once it is stored.")
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n" + var_blocks(decl) + "\n".join(code)
            + "\nEND_PROGRAM\n" + config(prog, "out0"))


def central_soe():
    prog = "CentralSoe"
    decl = [SOE_PARAMS, SOE_PARAM_VARS,
            "  rcv : MIP_Receiver;           (* records from the outstation *)",
            "  ho : PLC_SoeHandOver;         (* a record's entries to the server, processed when the SCADA took them *)",
            "  srv : MIP_SoeServer;          (* serves them to the SCADA (SOE_Control handshake) *)",
            "  tAck : TIME;                  (* srv.tAckTimeout *)"]
    decl += soe_located_io("MDP-810 unit 1")
    decl += [f"  (* the SCADA's registers: holding {SOE_SERVER_IMAGE}..{SOE_SERVER_IMAGE + SOE_REGS - 1} "
             f"(the relay's 40601..40626) *)",
             "  srvWrites AT %IW9 : WORD;       (* plcrt [slave] watch_count: the SCADA's writes to SOE_Control *)"]
    decl += [f"  srv{i} AT %QW{SOE_SERVER_IMAGE + i} : WORD;" for i in range(SOE_REGS)]
    decl += soe_status([("mRecLo", "records taken, low word"), ("mRecHi", "high word"),
                        ("mPutLo", "entries put into the server, low word"), ("mPutHi", "high word"),
                        ("mAckedLo", "entries the SCADA acknowledged, low word"), ("mAckedHi", "high word"),
                        ("mBadAcks", "refused writes to SOE_Control (mod 65536)"),
                        ("mBadRecords", "records not of whole entries (mod 65536)"),
                        ("mDup", "duplicates the receiver dropped (mod 65536)"),
                        ("mFailed", "transfers that failed at the receiver (mod 65536)"),
                        ("mFlags", "bit 0 server error (SCADA silent), bit 1 receiver error"),
                        ("mQueued", "entries in the server not yet acknowledged")])
    code = [SOE_PARAM_CODE]
    code += soe_io_before()
    code += ["tAck := T#1s * WORD_TO_DINT(pAckTimeout);",
             "(* the hand-over first, with the receiver's and the server's outputs of the last scan *)",
             "ho(xWaitScada := NOT xAckOnReceipt, xRecordValid := rcv.xRecordValid, aRecord := rcv.aRecord, uRecordLen := rcv.uRecordLen,",
             "   xTaken := srv.xTaken, udiPut := srv.udiPut, udiAcked := srv.udiAcked);",
             "rcv(xEnable := xRun, tTimeout := tTimeout, xAckByCaller := TRUE,",
             "    xRecordProcessed := ho.xProcessed, aRead := rd1, xReadValid := xRdValid1,",
             "    xReadError := rdErr1, wReadStatus := rdSt1,",
             "    xWriteDone := xWrDone1, xWriteError := wrErr1, xRetained := xRetain,",
             "    wSnapshots := snapSaved);",
             "srv(xEnable := xRun, xRetained := xRetain, tAckTimeout := tAck, xPut := ho.xPut,",
             "    aEntry := ho.aEntry, wCtrlWritten := srv1, wCtrlWrites := srvWrites,",
             "    wSnapshots := snapSaved);",
             "snapReq := rcv.xSnapshotReq OR srv.xSnapshotReq;",
             "(* the register area every scan: it also undoes a SCADA write to the read-only registers *)"]
    code += [f"srv{i} := srv.aRegs[{i}];" for i in range(SOE_REGS)]
    code += udint_words("mRecLo", "mRecHi", "ho.udiRecords")
    code += udint_words("mPutLo", "mPutHi", "srv.udiPut")
    code += udint_words("mAckedLo", "mAckedHi", "srv.udiAcked")
    code += ["mBadAcks := UDINT_TO_WORD(srv.udiBadAcks MOD 65536);",
             "mBadRecords := UDINT_TO_WORD(ho.udiBadRecords MOD 65536);",
             "mDup := UDINT_TO_WORD(rcv.udiDuplicates MOD 65536);",
             "mFailed := UDINT_TO_WORD(rcv.udiFailedTransfers MOD 65536);",
             "mFlags := WORD#0;",
             "IF srv.xError THEN mFlags := mFlags OR WORD#1; END_IF;",
             "IF rcv.xError THEN mFlags := mFlags OR WORD#2; END_IF;",
             "mQueued := UINT_TO_WORD(srv.uQueued);"]
    code += [c.replace(" OR xCyclic", "").replace("rcv1.", "rcv.") for c in io_after(1, "rcv")]
    doc = ("    The chain's central (issue 35, the pull way): MIP_Receiver with xAckByCaller hands each\n"
           "    record to PLC_SoeHandOver, which puts its entries into MIP_SoeServer; the record is\n"
           "    acknowledged over the radio only when the SCADA acknowledged all its entries.")
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n" + var_blocks(decl) + "\n".join(code)
            + "\nEND_PROGRAM\n" + config(prog, "cen0"))


UNICOS_MARKER = 0xFF80    # the frames' reference number: 16#FFFF + 123 registers would run past
                          # 65535, which plcrt's write range refuses; WinCC OA: [mod] addUnicosMarker
UNICOS_IMAGE = {"A": 400, "B": 530}   # the frames for driver A / B at %QW400.. / %QW530..


def unicos_io(d, k):
    """Located I/O of the write range to WinCC OA driver d (A, B): trigger %QX3.k etc."""
    b = UNICOS_IMAGE[d]
    return ([f"  uni{d}Trig AT %QX3.{k} : BOOL;      (* driver {d}: write trigger *)",
             f"  uni{d}Done AT %IX3.{2 * k} : BOOL;      (* driver {d}: write done (positive response) *)",
             f"  uni{d}Err AT %IX3.{2 * k + 1} : BOOL;       (* driver {d}: write failed *)",
             f"  uni{d}St AT %IW{13 + k} : WORD;         (* driver {d}: exception code or 1000 + errno *)",
             f"  uni{d}Len AT %QW{3 + k} : WORD;         (* driver {d}: registers of the frame *)"]
            + [f"  uni{d}{i} AT %QW{b + i} : WORD;" for i in range(123)])


def central_push():
    prog = "CentralPush"
    decl = [SOE_PARAMS, SOE_PARAM_VARS,
            "  rcv : MIP_Receiver;           (* records from the outstation *)",
            "  uni : MIP_UnicosEvents;       (* their entries to WinCC OA's UNICOS driver(s) *)",
            "  xRedundant : BOOL;            (* flags bit 2: a redundant pair of drivers *)"]
    decl += soe_located_io("MDP-810 unit 1")
    decl += unicos_io("A", 0) + unicos_io("B", 1)
    decl += soe_status([("mRecLo", "records handed over, low word"), ("mRecHi", "high word"),
                        ("mEvLo", "events the active driver took, low word"), ("mEvHi", "high word"),
                        ("mFrames", "frames handed over (mod 65536)"),
                        ("mRetries", "writes repeated after a failure (mod 65536)"),
                        ("mPassive", "frames the passive driver missed (mod 65536)"),
                        ("mDup", "duplicates the receiver dropped (mod 65536)"),
                        ("mFailed", "transfers that failed at the receiver (mod 65536)"),
                        ("mFlags", "bit 0 hand-over error (active driver), bit 1 receiver error, bit 2 passive driver failing")])
    code = [SOE_PARAM_CODE.replace("  xRun := pStart <> 0;",
                                   "  xRedundant := (pFlags AND 16#0004) <> 0;\n  xRun := pStart <> 0;")]
    code += soe_io_before()
    code += ["rcv(xEnable := xRun, tTimeout := tTimeout, xAckByCaller := TRUE,",
             "    xRecordProcessed := uni.xRecordProcessed, aRead := rd1, xReadValid := xRdValid1,",
             "    xReadError := rdErr1, wReadStatus := rdSt1,",
             "    xWriteDone := xWrDone1, xWriteError := wrErr1, xRetained := xRetain,",
             "    wSnapshots := snapSaved);",
             "(* flags bit 3, read every scan: driver B is the active one (a fail-over) *)",
             f"uni(xEnable := xRun, aRecord := rcv.aRecord, uRecordLen := rcv.uRecordLen,",
             f"    xRecordValid := rcv.xRecordValid, wMarker := WORD#{UNICOS_MARKER},",
             "    xRedundant := xRedundant, xActiveB := (pFlags AND 16#0008) <> 0,",
             "    xWriteDoneA := uniADone, xWriteErrorA := uniAErr, wWriteStatusA := uniASt,",
             "    xWriteDoneB := uniBDone, xWriteErrorB := uniBErr, wWriteStatusB := uniBSt);",
             "snapReq := rcv.xSnapshotReq;",
             "uniATrig := uni.xWriteReqA;",
             "uniALen := UINT_TO_WORD(uni.uWriteLenA);",
             "uniBTrig := uni.xWriteReqB;",
             "uniBLen := UINT_TO_WORD(uni.uWriteLenB);"]
    code += [f"uniA{i} := uni.aWriteA[{i}];" for i in range(123)]
    code += [f"uniB{i} := uni.aWriteB[{i}];" for i in range(123)]
    code += udint_words("mRecLo", "mRecHi", "uni.udiRecords")
    code += udint_words("mEvLo", "mEvHi", "uni.udiEvents")
    code += ["mFrames := UDINT_TO_WORD(uni.udiFrames MOD 65536);",
             "mRetries := UDINT_TO_WORD(uni.udiRetries MOD 65536);",
             "mPassive := UDINT_TO_WORD(uni.udiPassiveMissed MOD 65536);",
             "mDup := UDINT_TO_WORD(rcv.udiDuplicates MOD 65536);",
             "mFailed := UDINT_TO_WORD(rcv.udiFailedTransfers MOD 65536);",
             "mFlags := WORD#0;",
             "IF uni.xError THEN mFlags := mFlags OR WORD#1; END_IF;",
             "IF rcv.xError THEN mFlags := mFlags OR WORD#2; END_IF;",
             "IF uni.xPassiveError THEN mFlags := mFlags OR WORD#4; END_IF;"]
    code += [c.replace(" OR xCyclic", "").replace("rcv1.", "rcv.") for c in io_after(1, "rcv")]
    doc = ("    The chain's central (issue 35, the push way): MIP_Receiver with xAckByCaller hands each\n"
           "    record to MIP_UnicosEvents, which writes its entries as UNICOS event frames to WinCC\n"
           "    OA's driver (or both of a redundant pair); the record is acknowledged over the radio\n"
           "    only when the active driver answered positively.")
    return (HEADER.format(doc=doc) + f"PROGRAM {prog}\n" + var_blocks(decl) + "\n".join(code)
            + "\nEND_PROGRAM\n" + config(prog, "cen0"))


def mbconfig(devices):
    """An OpenPLC v3 mbconfig.cfg: devices = [(name, slave id, port, read start, write start)];
    each reads READ_REGS holding registers and writes WRITE_REGS (static MIP mode)."""
    out = [f'Num_Devices = "{len(devices)}"', 'Polling_Period = "100"', 'Timeout = "1000"']
    for i, (name, unit, port, rd, wr) in enumerate(devices):
        fields = [("name", name), ("slave_id", unit), ("protocol", "TCP"),
                  ("address", "127.0.0.1"), ("IP_Port", port), ("RTU_Baud_Rate", 115200),
                  ("RTU_Parity", "None"), ("RTU_Data_Bits", 8), ("RTU_Stop_Bits", 1),
                  ("RTU_TX_Pause", 0), ("Discrete_Inputs_Start", 0), ("Discrete_Inputs_Size", 0),
                  ("Coils_Start", 0), ("Coils_Size", 0), ("Input_Registers_Start", 0),
                  ("Input_Registers_Size", 0), ("Holding_Registers_Read_Start", rd),
                  ("Holding_Registers_Read_Size", READ_REGS), ("Holding_Registers_Start", wr),
                  ("Holding_Registers_Size", WRITE_REGS)]
        out += [f'device{i}.{k} = "{v}"' for k, v in fields]
    return "\n".join(out) + "\n"


def openplc_configs(stations):
    """The OpenPLC configurations: the outstation (TRM-810, port 15021) and a central with one
    device per station (MDP-810 port 15020, unit id = station)."""
    return [("openplc/outstation-mbconfig.cfg", mbconfig([("trm", 1, 15021, 2198, 2001)])),
            ("openplc/central-mbconfig.cfg",
             mbconfig([(f"mdp{s}", s, 15020, 198, 10) for s in range(1, stations + 1)]))]


def main(argv=()):
    ap = argparse.ArgumentParser(prog="gen_programs.py", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--openplc-stations", type=int, default=OPENPLC_STATIONS, metavar="N",
                    help=f"stations in the central's OpenPLC configuration "
                         f"(default {OPENPLC_STATIONS}, at most {MAX_MB_IO // READ_REGS})")
    ap.add_argument("--many-stations", type=int, default=MANY_STATIONS, metavar="N",
                    help=f"receivers in plc/central_many.st, the central of a large network "
                         f"(default {MANY_STATIONS}, 1..{MAX_UNIT})")
    ap.add_argument("-o", "--outdir", help="write here instead of plc/")
    a = ap.parse_args(list(argv))
    out = Path(a.outdir) if a.outdir else HERE
    if not 1 <= a.openplc_stations <= MAX_STATIONS:
        print(f"gen_programs.py: error: --openplc-stations {a.openplc_stations}: the central "
              f"program has stations 1..{MAX_STATIONS}", file=sys.stderr)
        return 2
    if not 1 <= a.many_stations <= MAX_UNIT:
        print(f"gen_programs.py: error: --many-stations {a.many_stations}: one MDP-810 serves "
              f"unit ids 1..{MAX_UNIT}", file=sys.stderr)
        return 2
    files = [("outstation.st", outstation(False)), ("central.st", central(False)),
             ("outstation_bidi.st", outstation(True)), ("central_bidi.st", central(True)),
             ("central_many.st", central_many(a.many_stations)),
             ("outstation_soe.st", outstation_soe()), ("central_soe.st", central_soe()),
             ("central_push.st", central_push())]
    files += openplc_configs(a.openplc_stations)
    for name, text in files:              # check everything before writing anything
        if name.endswith(".cfg"):
            try:
                check_openplc(text, f"plc/{name}")
            except LimitError as e:
                print(f"gen_programs.py: {e} (--openplc-stations {a.openplc_stations}: "
                      f"at most {MAX_MB_IO // READ_REGS} stations of {READ_REGS} registers)",
                      file=sys.stderr)
                return 2
    for name, text in files:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
        print(f"wrote plc/{name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
