"""What the example programs share: the register layout of their located image and %MW blocks,
the parameter words, and the ST fragments every program is assembled from."""
from . import mipglue as glue

OPENPLC_STATIONS = 2      # devices in the committed plc/openplc/central-mbconfig.cfg
MAX_STATIONS = 4          # receivers in the central programs (devices 1..4)
READ_REGS = 125           # one FC3 at the read-status register: status, count, 123 data
WRITE_REGS = 123          # one FC16 at the first write register
WINDOW = 160              # PLC_RecordStore.aWindow

# plc/central_many.st: ONE read and ONE write range for all stations, r_<i> / w_<i>
GLUE_MANY = glue.Layout(read_base=100, read_count=READ_REGS, write_base=100, write_count=WRITE_REGS,
                        read_array="rd", write_array="aWr", read_prefix="r_", write_prefix="w_",
                        numbered=False)
glue.check(GLUE_MANY, "openplc")


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


def config(prog, inst, task="tMain"):
    """The CONFIGURATION that runs PROGRAM `prog` as instance `inst`, every 10 ms in task `task`
    (the example programs' and the tests' one task)."""
    return (f"\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            f"    TASK {task}(INTERVAL := T#10ms, PRIORITY := 0);\n"
            f"    PROGRAM {inst} WITH {task} : {prog};\n  END_RESOURCE\nEND_CONFIGURATION\n")


HEADER = "(* GENERATED by plc/gen_programs.py -- edit the generator, not this file.\n{doc} *)\n"


