"""The chain's programs (issue 35, docs/chain.md): plc/outstation_soe.st, plc/central_soe.st and
plc/central_push.st."""
from .common import ms_to_time, located_io, io_before, io_after, var_blocks, config, HEADER


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
             "IF rdr.xCaughtUp THEN mFlags := mFlags OR WORD#2; END_IF;",
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
            "  xRedundant : BOOL;            (* flags bit 2: a redundant pair of drivers *)",
            "  uniARep, uniBRep : MIP_T_UnicosReply;   (* the drivers' answers to uni's writes *)"]
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
             "uniARep.xWriteDone := uniADone;", "uniARep.xWriteError := uniAErr;",
             "uniARep.wWriteStatus := uniASt;",
             "uniBRep.xWriteDone := uniBDone;", "uniBRep.xWriteError := uniBErr;",
             "uniBRep.wWriteStatus := uniBSt;",
             "(* flags bit 3, read every scan: driver B is the active one (a fail-over) *)",
             "uni(xEnable := xRun, aRecord := rcv.aRecord, uRecordLen := rcv.uRecordLen,",
             f"    xRecordValid := rcv.xRecordValid, wMarker := WORD#{UNICOS_MARKER},",
             "    xRedundant := xRedundant, xActiveB := (pFlags AND 16#0008) <> 0,",
             "    stReplyA := uniARep, stReplyB := uniBRep);",
             "snapReq := rcv.xSnapshotReq;",
             "uniATrig := uni.stRequestA.xWriteReq;",
             "uniALen := UINT_TO_WORD(uni.stRequestA.uWriteLen);",
             "uniBTrig := uni.stRequestB.xWriteReq;",
             "uniBLen := UINT_TO_WORD(uni.stRequestB.uWriteLen);"]
    code += [f"uniA{i} := uni.stRequestA.aWrite[{i}];" for i in range(123)]
    code += [f"uniB{i} := uni.stRequestB.aWrite[{i}];" for i in range(123)]
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


