"""plc/central_many.st, the central of a large network (any 1..247 stations), still generated
whole (its per-station lines depend on N). The other logger programs are written by hand and
only their located image is generated (mipprograms.image)."""
from . import mipglue as glue
from .common import GLUE_MANY, PARAMS, PARAM_VARS, PARAM_CODE, var_blocks, config, HEADER


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
    code += ["""\
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


