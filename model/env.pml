/* env.pml: the environment of the MIP logger transfer, as the emulator (emulator/src/mipemu.c)
 * implements it, in dynamic mode: two modems (MDP-810 = side 0, TRM-810 = side 1) with their
 * write and read areas and read-status bits, a time-slot radio that loses telegrams and repeats
 * an unconfirmed block at every poll, PLC timers that count poll slots, and the ghost variables
 * the properties are written over.
 *
 * A block is abstracted to its first two registers and two ghost fields:
 *   c  register 0 (record counter or acknowledgement of the stream this model checks)
 *   x  register 1 (what our extensions put there, e.g. a marker; 0 for a note peer)
 *   t  ghost: the transfer attempt a record belongs to (0 = not a record)
 *   i  ghost: the record's index in its transfer, 1..NREC
 * The ghost fields never influence a peer: they only feed the assertions.
 *
 * Configuration (spin -D...; defaults below): NREC records per transfer, NT transfers the
 * sending application submits, MAXC lost slots in a row (a slot after MAXC lossy slots loses
 * nothing: loss < 1), TT timer expiry in poll slots, RST_S / RST_R restarts of the sending /
 * receiving PLC, SSIDE the sender's modem (1 = outstation sends to the central, as in the
 * note's example; 0 = central sends to the outstation), POLLED drive (1) or spontaneous (0).
 *
 * Bidirectional layout (note 2.2, MIP_Link), BIDI = 1: every block carries both streams'
 * registers, the checked stream's (c: record counter on the sender's side, acknowledgement on
 * the receiver's) and the other stream's (abstracted away: x stays 0, no echo). The other
 * stream shows only as NBW extra writes per side at any moment (its records and its
 * acknowledgements), each carrying that side's current state of the checked stream: they
 * overwrite unsent blocks, re-send records and acknowledgements and produce new telegrams
 * with an unchanged number. C3 = 1 (configuration rule C3 of PROTOCOL.md: each side reads its
 * read area at least once per poll cycle) keeps the radio from delivering a block into a read
 * area that still holds unread data; C3 = 0 lets a PLC be arbitrarily slow.
 *
 * Warm restarts (issue 16; our blocks only, our_peers.pml): WRST_S / WRST_R warm restarts of the
 * sending / receiving PLC. Its retained state (the whole block instance and the application's
 * retained data: the logger's read-out state, the receiver's store) is rolled back to the last
 * snapshot, as after a `kill -9` of a soft-PLC that saves snapshots now and then; the modems keep
 * running. DURABLE = 1: "durable before visible" (PROTOCOL.md W1, W2): a snapshot is taken before
 * each first write of a new record and before each acknowledgement write; DURABLE = 0: snapshots
 * at any moment only (a periodic save), which the model must find unsafe. With warm restarts and
 * no cold ones (WARMONLY) any failure (an error of either block, an open transfer dropped) and any
 * transfer completed twice is a violation (WARMFAIL, DUP_ORDER).
 */

#ifndef NREC
#define NREC 3
#endif
#ifndef NT
#define NT 2
#endif
#ifndef MAXC
#define MAXC 1
#endif
#ifndef TT
#define TT 2
#endif
#ifndef OT
#define OT (3 * TT + 1)      /* the out-of-step bound 3 x tTimeout of P11 / P21 (timers start at 1) */
#endif
#ifndef RST_S
#define RST_S 0
#endif
#ifndef RST_R
#define RST_R 0
#endif
#ifndef SSIDE
#define SSIDE 1
#endif
#ifndef POLLED
#define POLLED 0
#endif
#ifndef BIDI
#define BIDI 0
#endif
#ifndef NBW
#define NBW 2
#endif
#ifndef C3
#define C3 1
#endif
#ifndef WRST_S
#define WRST_S 0
#endif
#ifndef WRST_R
#define WRST_R 0
#endif
#ifndef DURABLE
#define DURABLE 1
#endif
#define WARMONLY (RST_S == 0 && RST_R == 0 && (WRST_S > 0 || WRST_R > 0))

#define MDP 0
#define TRM 1
#define S   SSIDE            /* the sender's modem */
#define R   (1 - SSIDE)      /* the receiver's modem */
#define LAST 255             /* 16#FFFF: the last record of a transfer */

/* record counter of the record with index i */
#define CTR(i) ((i) < NREC -> (i) : LAST)

/* ---- modems: [MDP] and [TRM] ---- */
byte wc[2], wx[2], wt[2], wi[2];   /* write area (the block queued for the radio) */
bool pend[2];                      /* read-status bit 4: write data unconfirmed */
bool waitb[2];                     /* read-status bit 1: write data waiting (not yet sent) */
bool onair[2];                     /* the block taken for the current slot is still the queued one */
byte rc[2], rx[2], rt[2], ri[2];   /* read area (the last block received) */
bool rnew[2];                      /* read-status bit 0: new read data */

/* ---- radio ---- */
byte ph;                           /* 0: next is the poll (MDP->TRM), 1: the answer, 2: the ack */
bool dhas, uhas;                   /* the slot's poll / answer carries a block */
byte closs;                        /* lossy slots in a row */
bool slotlost;                     /* this slot lost a telegram */
byte tmr[2];                       /* PLC timers per side: slots since the PLC's last write */
byte otmr[2];                      /* out-of-step timers of our blocks (P11/P21), saturating at OT */
bool r_stuck;                      /* our receiver raised MIP_ERR_PEER_OUT_OF_STEP (P21) */

/* ---- bounded faults ---- */
byte rst_s = RST_S, rst_r = RST_R;
byte wrst_s = WRST_S, wrst_r = WRST_R;
#if BIDI
byte nbw[2] = NBW;                 /* extra writes left per side (the other stream's traffic) */
#endif

/* ---- ghosts ---- */
byte g_next;                       /* last transfer attempt id the sender used */
byte a_t, a_i;                     /* receiver application: transfer being delivered, last index */
int  compl;                        /* bit t: the receiver completed attempt t with every record */
int  sabort;                       /* bit t: the sender gave attempt t up (restart or error) */
bool s_fin;                        /* the sending application has finished all NT transfers */
byte s_done, s_err;                /* transfers the sender reported done / failed */
byte r_err;                        /* transfers the receiver closed with an error */

/* A Modbus FC16 write of one block to the first write register (dynamic mode): replaces the
 * queued block, sets bits 1 and 4; a block already taken for the current slot stays on air but
 * its confirmation no longer clears the new one (the emulator's generation check). */
inline mb_write(wm, vc, vx, vt, vi) {
    d_step {
        printf("@ M%d PLC writes [%d,%d] (t%d#%d)\n", wm, vc, vx, vt, vi);
        wc[wm] = vc; wx[wm] = vx; wt[wm] = vt; wi[wm] = vi;
        pend[wm] = 1; waitb[wm] = 1; onair[wm] = 0;
        if
        :: (POLLED && wm == R) || (!POLLED && wm == S) -> tmr[wm] = 0
        :: else -> skip
        fi
    }
}

/* BIDI: a write of the same side's block caused by the other stream (its record or its
 * acknowledgement): carries the current state of the checked stream; the checked stream's
 * repetition timer is not restarted (the other part of MIP_Link wrote). */
inline mb_write_other(wm, vc, vt, vi) {
    d_step {
        printf("@ M%d PLC writes [%d] for the other stream (t%d#%d)\n", wm, vc, vt, vi);
        wc[wm] = vc; wx[wm] = 0; wt[wm] = vt; wi[wm] = vi;
        pend[wm] = 1; waitb[wm] = 1; onair[wm] = 0;
        nbw[wm]--
    }
}

/* SPLITREAD (issue 38): the PLC's master reads the read area in parts (plcrt's status_first:
 * status, count and the counter first, the rest of the block only when needed) and keeps what
 * it did not read from its image of the last whole read (not retained: empty after a restart).
 * 1: the rest only with bit 0 (plcrt before the fix). A read whose answer was lost (a PLC
 * killed while the answer was on the line: here a warm restart after the read) took bit 0, so
 * the restarted PLC sees the new counter with data of no read: must fail. 2: also when the
 * image holds no block or its counter differs (the fix): must hold. 0: one FC3. */
#ifndef SPLITREAD
#define SPLITREAD 0
#endif
#if SPLITREAD
byte imc[2], imx[2], imt[2], imi[2];   /* the PLC's image of the last whole read; imc 0: none */
#define im_reset(side) imc[side] = 0; imx[side] = 0; imt[side] = 0; imi[side] = 0
#else
#define im_reset(side) skip
#endif

/* A Modbus read of status, count and read data in one FC3: returns the block and whether it
 * was new; clears bit 0 after the answer was composed. Used inside the caller's d_step, which
 * decides on the block and clears the values again (clr_read), so that old reads do not
 * multiply the states. */
inline mb_read(rm, isnew, oc, ox, ot, oi) {
    isnew = rnew[rm]; oc = rc[rm]; ox = rx[rm]; ot = rt[rm]; oi = ri[rm];
#if SPLITREAD
    if
    :: !isnew && oc != 0 && (SPLITREAD == 1 || imc[rm] == oc) ->
        ox = imx[rm]; ot = imt[rm]; oi = imi[rm]       /* the rest from the image */
    :: else -> imc[rm] = oc; imx[rm] = ox; imt[rm] = ot; imi[rm] = oi   /* read whole */
    fi;
#endif
    if :: isnew -> printf("@ M%d PLC reads new [%d,%d] (t%d#%d)\n", rm, oc, ox, ot, oi) :: else -> skip fi;
    rnew[rm] = 0
}

inline clr_read(isnew, oc, ox, ot, oi) {
    isnew = 0; oc = 0; ox = 0; ot = 0; oi = 0
}

inline deliver(from, to) {
    printf("@ radio M%d -> M%d [%d,%d] (t%d#%d)\n", from, to, wc[from], wx[from], wt[from], wi[from]);
    rc[to] = wc[from]; rx[to] = wx[from]; rt[to] = wt[from]; ri[to] = wi[from];
    rnew[to] = 1
}

inline confirm(cm) {
    if
    :: onair[cm] -> pend[cm] = 0; onair[cm] = 0; printf("@ radio confirms M%d block [%d]\n", cm, wc[cm])
    :: else -> skip
    fi
}

inline maylose(lost) {
    if
    :: closs < MAXC -> lost = 1; slotlost = 1; printf("@ radio telegram lost (phase %d)\n", ph)
    :: true -> lost = 0
    fi
}

inline endslot() {
    if
    :: slotlost -> closs++
    :: else -> closs = 0
    fi;
    slotlost = 0;
    ph = 0;
    /* only the timer that drives repetitions runs: the sender's (spontaneous) or the
     * receiver's (polled); the other one is never read */
#if POLLED
    if :: tmr[R] < TT -> tmr[R]++ :: else -> skip fi;
#else
    if :: tmr[S] < TT -> tmr[S]++ :: else -> skip fi;
#endif
    /* an out-of-step timer runs from 1 (started) to OT (expired); 0 = stopped */
    if :: otmr[0] > 0 && otmr[0] < OT -> otmr[0]++ :: else -> skip fi;
    if :: otmr[1] > 0 && otmr[1] < OT -> otmr[1]++ :: else -> skip fi
}

/* Never set: names a global deadlock (every process blocked) in the text spin prints. The
 * radio's timeout branch below is the only check of it: pan's own invalid-end-state check is
 * off in the acceptance-cycle search (pan -a), which covers every state (the claim at the end). */
bool DEADLOCK;

/* The time-slot radio between the MDP and one TRM (mipemu.c step()): poll, answer, ack. */
active proctype Radio() {
    bool lost;
    do
    :: d_step { ph == 0 && !(BIDI && C3 && pend[MDP] && rnew[TRM]) ->
        /* poll: the MDP sends its pending block (or an empty poll); bit 1 clears when sent */
        dhas = pend[MDP]; onair[MDP] = dhas;
        if :: dhas -> waitb[MDP] = 0 :: else -> skip fi;
        maylose(lost);
        if
        :: lost -> endslot()
        :: else -> if :: dhas -> deliver(MDP, TRM) :: else -> skip fi; ph = 1
        fi }
    :: d_step { ph == 1 && !(BIDI && C3 && pend[TRM] && rnew[MDP]) ->
        /* answer: the TRM sends its pending block (or an empty answer); it confirms the poll */
        uhas = pend[TRM]; onair[TRM] = uhas;
        if :: uhas -> waitb[TRM] = 0 :: else -> skip fi;
        maylose(lost);
        if
        :: lost -> endslot()
        :: else ->
            if :: dhas -> confirm(MDP) :: else -> skip fi;
            if
            :: uhas -> deliver(TRM, MDP); ph = 2
            :: else -> endslot()
            fi
        fi }
    :: d_step { ph == 2 ->
        /* ack: the MDP confirms the answer's block */
        maylose(lost);
        if :: !lost -> confirm(TRM) :: else -> skip fi;
        endslot() }
    :: timeout -> assert(DEADLOCK)   /* no process can move: not even the radio (C3) */
    od
}

/* ---- the receiving application (ghost) ---- */

/* Never set: each names the property in the text spin prints for a violated assertion.
 * -DSEEK=K_<name> (model/run.py's search for one documented weakness) sets every other one,
 * so that the search looks for a run that violates this property and no other stops it. */
#define K_GAP 1
#define K_MIX 2
#define K_DUP_ORDER 3
#define K_LOST 4
#define K_SILENT 5
#define K_DONE 6
#define K_WARMFAIL 7
#ifndef SEEK
#define SEEK 0
#endif
bool GAP = (SEEK != 0 && SEEK != K_GAP), MIX = (SEEK != 0 && SEEK != K_MIX),
     DUP_ORDER = (SEEK != 0 && SEEK != K_DUP_ORDER), LOST = (SEEK != 0 && SEEK != K_LOST),
     SILENT = (SEEK != 0 && SEEK != K_SILENT), DONE = (SEEK != 0 && SEEK != K_DONE),
     WARMFAIL = (SEEK != 0 && SEEK != K_WARMFAIL);

/* a record handed to the application */
inline app_record(gt, gi) {
    if
    :: a_t == 0 ->
        assert(gi == 1 || GAP);          /* a transfer delivered without its first record */
        a_t = gt; a_i = 1
    :: else ->
        assert(gt == a_t || MIX);        /* records of two transfers in one */
        assert(gi > a_i || DUP_ORDER);   /* delivered twice or out of order */
        assert(gi == a_i + 1 || GAP);    /* a record skipped */
        a_i = gi
    fi
}

/* the receiver reports the transfer complete */
inline app_complete() {
    assert((a_t != 0 && a_i == NREC) || LOST); /* completed without every record */
    assert(!WARMONLY || (compl & (1 << a_t)) == 0 || DUP_ORDER); /* a transfer stored twice */
    compl = compl | (1 << a_t);
    a_t = 0; a_i = 0
}

/* the receiver drops the transfer it was delivering; err: it says so (xError) */
inline app_drop(err) {
    assert(err || a_t == 0 || (sabort & (1 << a_t)) || SILENT); /* dropped although its sender goes on, no error */
    assert(!WARMONLY || a_t == 0 || WARMFAIL);   /* warm restarts only: an open transfer dropped */
    if :: err && a_t != 0 -> r_err++ :: else -> skip fi;
    a_t = 0; a_i = 0
}

/* ---- the sending application (ghost) ---- */
inline app_sent(st) {
    assert((compl & (1 << st)) || DONE); /* the sender reports done, the receiver did not complete it */
    s_done++;
    if :: s_done + s_err == NT -> s_fin = 1 :: else -> skip fi
}

inline app_failed(ft) {
    assert(!WARMONLY || WARMFAIL);               /* warm restarts only: the sender failed */
    sabort = sabort | (1 << ft);
    s_err++;
    if :: s_done + s_err == NT -> s_fin = 1 :: else -> skip fi
}

/* progress: every transfer the sender was given ends, done or failed, or our receiver says
 * with xError that its peer is out of step (P21: the note sender cannot go on), i.e.
 * <> (s_fin || r_stuck). The claim is the negation, [] !(s_fin || r_stuck), written by hand so
 * that it goes on after the goal (T_after, not accepting) instead of blocking there as the one
 * spin makes from the ltl formula: the acceptance-cycle search then also visits every state
 * after the sender finished (a rollback after the transfer, an idle link's record 0) and checks
 * its assertions, so one search proves both progress and safety. It accepts exactly the runs
 * of [] !(s_fin || r_stuck), which is stutter-invariant, as partial-order reduction needs. */
never {
accept_wait:
    do
    :: !(s_fin || r_stuck)
    :: (s_fin || r_stuck) -> break
    od;
T_after:
    do
    :: true
    od
}
