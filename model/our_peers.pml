/* our_peers.pml: MIP_Sender and MIP_Receiver of st_lib/ as the rules P1..P24 of
 * st_lib/PROTOCOL.md define them; with BIDI = 1 the two halves of MIP_Link (bidirectional
 * layout: P9 instead of the echo P8, record 0 of an idle link P16, the other stream's writes). Labels are the state names of PROTOCOL.md section 9
 * (E_MIP_SenderState / E_MIP_ReceiverState without the MIP_ prefix); the rule numbers stand in
 * the comments.
 *
 * Abstractions:
 *  - The check value chk(block) (PROTOCOL.md section 1) is CHK(t, i): records of different
 *    attempts have different content. The residual of P8 (a restarted sender whose record N is
 *    identical to the old one) delivers the same data and is not modelled.
 *  - The echo [ack, 16#4D50, chk] (P8/P24) is register 1 = x: x = 0 no magic (a note
 *    receiver), x = 1 magic with chk 0 (ack 0), else magic with chk x.
 *  - tTimeout = TT poll slots; the out-of-step bound 3 x tTimeout (P11/P21) = OT slots.
 *  - The caller's chunk and write handshakes answer at once (SND_GET_CHUNK is passed through;
 *    WR_REQUEST..WR_CLEAR is the atomic mb_write); P10 (cyclic I/O) does not arise.
 *  - P14 (uMaxRetries > 0), P22 (tTransferTimeout > 0) are off, as by default; rate limiting of
 *    repeated acknowledgements (P17/P20) is left out (every such telegram is answered).
 */

#define CHK(t, i) ((t) * 8 + (i))
#define CHK0 1


/* decisions (besides those of note_peers.pml) */
/* P19 variants for findings: 0 = as PROTOCOL.md (L = 0 or L = 16#FFFF with another check,
 * not where it may be the tail of a lost transfer), 1 = only L = 16#FFFF with another check,
 * 2 = no lone 16#FFFF */
#ifndef P19_MODE
#define P19_MODE 0
#endif

/* P8 variant for findings: 0 = as PROTOCOL.md (the echo's check value must match), 1 = the
 * number alone counts (what the echo buys) */
#ifndef P8_MODE
#define P8_MODE 0
#endif

/* P9 variant for findings (bidirectional): 0 = as PROTOCOL.md (the own modem confirmed the
 * record), 1 = the number alone counts (what the own-modem confirmation buys) */
#ifndef P9_MODE
#define P9_MODE 0
#endif

/* receiver's first read after xEnable: 0 = as PROTOCOL.md section 1 (a telegram; only P19 and
 * P21 leave it out), 1 = variant: a block already there at the first read (bit 0 clear) is
 * never taken as a record */
#ifndef RFIRST_MODE
#define RFIRST_MODE 0
#endif

/* which acknowledgements carry the echo (P24): 1 = as PROTOCOL.md, only acknowledgements 0 and
 * 1 (a stale acknowledgement can pass for the record in flight only when that is record 1:
 * after it, every number the sender waits for was written by the receiver in this session);
 * 0 = variant: every acknowledgement (the rule before; two registers more per acknowledgement) */
#ifndef ECHO_MODE
#define ECHO_MODE 1
#endif

/* the acknowledgement's register 1: the echo's check value (P24), none in the bidirectional
 * layout (register 1 is the other stream's counter there) */
#if BIDI
#define ECHO(l, k) 0
#else
#define ECHO(l, k) ((ECHO_MODE == 1 && (l) > 1) -> 0 : (k))
#endif

/* BIDI: the sender's spontaneous repeat comes after a read (every scan of MIP_Link reads);
 * otherwise weak fairness alone lets a PLC repeat forever without ever reading, which hides
 * the out-of-step acknowledgement of P11 (a model artefact the uni configurations keep). And
 * (PROTOCOL.md P3, bidirectional) only once a read saw the own modem confirm the block
 * (conf): until then the modem sends the unconfirmed block again at every poll itself, and a
 * repeat would only keep the confirmation P9 waits for from ever being seen */
#if BIDI
#define SCANREAD (rd && !pend[S] && conf)
#else
#define SCANREAD 1
#endif

/* the sender's window (issue 15): 1 = stop and wait (P3..P8), 2 = pipelined (P27): the next
 * record is written as soon as the own modem confirmed the one in flight (read-status bit 4
 * clear after its write), before the acknowledgement came; never the last record (16#FFFF),
 * which waits for the acknowledgement of the one before it. Spontaneous drive, both layouts;
 * bidirectional: the other stream's writes carry the newest record written, and the pipelined
 * record, once the acknowledgement of the one before made it the record in flight, is counted
 * with P9 like any other. */
#ifndef WIN
#define WIN 1
#endif
/* P27 variants for findings: PIPE_LAST 1 = the last record is pipelined too; PIPE_FIRST 1 =
 * record 2 is pipelined before record 1 was acknowledged (as PROTOCOL.md: only from record 2
 * on, after an acknowledgement of this session was seen) */
#ifndef PIPE_LAST
#define PIPE_LAST 0
#endif
#ifndef PIPE_FIRST
#define PIPE_FIRST 0
#endif
/* PIPE_KEEP 1 = the window stays open after a repeat went back (a receiving PLC that reads
 * slower than the records arrive then sees every record overwritten by the next one) */
#ifndef PIPE_KEEP
#define PIPE_KEEP 0
#endif
/* PIPE_CLOSE: after a repeat went back, the window stays closed until this many records
 * were acknowledged (MIP_Sender: 8). The configurations check 1, the earliest reopening: a
 * sender that reopens later only leaves out pipelined writes this one may make */
/* PIPE_P9 1 = variant: bidirectional, the acknowledgement of the pipelined record counts only
 * with P9 for its own block (conf2, fresh2). Not the rule: after a repeat went back the block
 * in the modem is the older record's, so that confirmation may never be seen; the sender then
 * cannot count an acknowledgement its receiver keeps sending (the block: a silent hang; here
 * the out-of-step error). The rule (0) counts it by its number: from record 3 on, after record
 * 1 of this session was acknowledged, C3 makes every number the peer writes one of this
 * session (as the echo does for the unidirectional layout) */
#ifndef PIPE_P9
#define PIPE_P9 0
#endif
#ifndef PIPE_CLOSE
#define PIPE_CLOSE 1
#endif
/* PIPE_FRESH 1 = variant (bidirectional): the acknowledgement of the pipelined record counts
 * only when it came with a telegram after that record's write. Window 2 in this layout is
 * withdrawn (PROTOCOL.md P27: win2/bidi/...+rst-snd lose a record); this variant does not
 * save it (the peer's writes carry its old session's number until it reads our record 1):
 * model/run.py -k win2/bidi -D PIPE_FRESH=1 finds the same GAP */
#ifndef PIPE_FRESH
#define PIPE_FRESH 0
#endif
#if WIN == 2 && POLLED
#error WIN 2: spontaneous drive
#endif
#if WIN == 2 && BIDI && WRST_S
#error WIN 2: the bidirectional layout runs window 1 (P27)
#endif
/* WIN 2 with warm restarts of the sender (PROTOCOL.md P27, W1): PIPEGATE 1 = the rule: the
 * pipelined record's first write, like any other new record's, only after a snapshot holds
 * the sender with that record built (PC_PIPE); 0 = variant for findings: only periodic
 * snapshots around the pipelined write. PIPERESTORE 1 = the rule: the pipelined state
 * (ahead, sent2, sconf, nopipe) is part of the snapshot like the rest of the instance (W3);
 * 0 = variant for findings: a warm restart comes back without it (stop and wait for the
 * older record) */
/* With window 2 our receiver's P21 (peer out of step) is reachable with no restart at all: the
 * pipelined record overwrote the unread one before it, the receiver ignores it (P20), and the
 * sender's repeat comes later than the bound (in the model a PLC's scan is not tied to the poll
 * slots; on a plant: a receiving PLC slower than the radio and repeats lost). The win2
 * configurations without restarts allow it (an error, reported; nothing lost or doubled), so
 * the warm ones (WARMONLY: no error at all) do too: what they check is that a warm restart
 * adds no loss, no duplicate, no transfer stored twice, no failure of the sender */
#define R_OOS_WARMOK (WIN == 2)
#ifndef PIPEGATE
#define PIPEGATE 1
#endif
#ifndef PIPERESTORE
#define PIPERESTORE 1
#endif

/* W4 (bidirectional layout with warm restarts, PROTOCOL.md section 11): MIP_Link's one write
 * carries both parts' state, so it goes out only when the last snapshot holds every part it
 * carries. LINKGATE 1 = the rule: the other stream's writes wait while this side's checked
 * part has a change no snapshot holds (a new record built, W1; a new acknowledgement, W2).
 * LINKGATE 0 = variant for findings: the other part's write carries the unsaved state (one
 * such write may come between the change and its snapshot, and a warm restart right after
 * it), which the model must find unsafe. */
#ifndef LINKGATE
#define LINKGATE 1
#endif
#define W4_GATED (LINKGATE == 1 && DURABLE)
/* IDLEGATE 0 = variant for findings: the idle link's record 0 waits for no snapshot (the part
 * of W4 that acts only after the sender finished; tests/model shows the search still sees it) */
#ifndef IDLEGATE
#define IDLEGATE 1
#endif

#define A_RESET  5   /* P12: acknowledgement 0 after a counted record */
#define A_OOS    6   /* P11: out of step for the whole bound */

/* ---- warm restarts (WRST_S / WRST_R, DURABLE; env.pml): the last retained snapshot of each
 * side. The initial values are the snapshot of a PLC that has saved nothing yet (its start).
 * A snapshot holds the whole block instance (IEC: an instance declared RETAIN) and the
 * application's retained data; pc says where the block was (its state). ---- */
#define PC_IDLE 0    /* SND_IDLE: between transfers */
#define PC_SEND 1    /* the record is built, its first write follows (W1) */
#define PC_ACK  2    /* SND_WAIT_ACK */
#define PC_REQ  3    /* SND_WAIT_REQUEST (polled) */
#define PC_PIPE 4    /* WIN 2: record cur + 1 is built, its first (pipelined) write follows (W1) */
#if WIN == 2
bool ss_ahead, ss_sent2, ss_sconf;   /* WIN 2: the pipelined state in the snapshot (W3) */
byte ss_nopipe;
#define S_CHANGED_PIPE || ss_ahead != ahead || ss_sent2 != sent2 || ss_sconf != sconf || ss_nopipe != nopipe
#else
#define S_CHANGED_PIPE
#endif
byte ss_cur, ss_t, ss_ctr, ss_pc, ss_gnext, ss_sdone, ss_serr;
bool ss_oos, ss_conf, ss_fresh, ss_first = 1, ss_rd, ss_sfin;
byte sr_L, sr_Lchk = CHK0, sr_oldchk, sr_at, sr_ai, sr_rerr;
bool sr_first = 1, sr_uoos, sr_sempty, sr_nolone;
int  sr_compl;
#if SPLITREAD
byte sr_dnum;                /* the receiver's MIP_Internal_ReadDecoder: the last number taken */
#define DNUM_NEW(nc) (nc != dnum)
#else
#define DNUM_NEW(nc) 0
#endif

/* the sender's state differs from its last snapshot (a periodic save would change it) */
/* the last snapshot holds the sender gone idle (W4: its image is record 0) */
#define S_IDLE_HELD (WRST_S == 0 || !W4_GATED || !IDLEGATE || ss_pc == PC_IDLE)

/* the last snapshot holds the record the sender has built (W4) */
#define S_HELD (WRST_S == 0 || !W4_GATED || (ss_t == t && ss_cur == cur))

#define S_CHANGED (ss_t != t || ss_cur != cur || ss_conf != conf || ss_fresh != fresh || ss_oos != oos || ss_first != first S_CHANGED_PIPE)

inline s_save(pc) {
    d_step {
        ss_cur = cur; ss_t = t; ss_ctr = ctr; ss_oos = oos; ss_conf = conf; ss_fresh = fresh;
        ss_first = first; ss_rd = rd; ss_pc = pc;
        ss_gnext = g_next; ss_sdone = s_done; ss_serr = s_err; ss_sfin = s_fin;
#if WIN == 2
        ss_ahead = ahead; ss_sent2 = sent2; ss_sconf = sconf; ss_nopipe = nopipe;
#endif
        printf("@ sender snapshot (pc %d, record %d of t%d)\n", pc, cur, t)
    }
}

/* the last snapshot holds the number the receiver acknowledges (W4) */
#define R_HELD (WRST_R == 0 || !W4_GATED || (sr_L == L && sr_Lchk == Lchk))

#define R_CHANGED (sr_L != L || sr_Lchk != Lchk || sr_first != first || sr_uoos != uoos || sr_sempty != sempty || sr_nolone != nolone || sr_oldchk != oldchk || sr_at != a_t || sr_ai != a_i)

inline r_save() {
    d_step {
        sr_L = L; sr_Lchk = Lchk; sr_oldchk = oldchk; sr_first = first; sr_uoos = uoos;
        sr_sempty = sempty; sr_nolone = nolone;
        sr_at = a_t; sr_ai = a_i; sr_compl = compl; sr_rerr = r_err;
#if SPLITREAD
        sr_dnum = dnum;
#endif
        printf("@ receiver snapshot (L %d)\n", L)
    }
}

ACTIVE_OurSender proctype OurSender() {
    byte cur, t, ctr, prev, nc, nx, nt, ni, act;
    bool nw, first = 1, oos;
    bool conf, fresh;        /* BIDI P9: own modem confirmed / a new telegram since the write */
    bool rd;                 /* BIDI: read since the last write (a scan reads before it repeats) */
    bool newrec;             /* the record in aWrite was not written yet (W1) */
#if WIN == 2
    /* (all WIN 2 code is in #if: with window 1 the model is the one checked before P27) */
    bool ahead;              /* WIN 2: the last write was record cur + 1 (P27) */
    bool sent2;              /* WIN 2: record cur + 1 was written in this attempt: its
                              * acknowledgement counts for both, also after a repeat went back */
    bool sconf;              /* WIN 2: the own modem confirmed the last write (bit 4 clear) */
    byte pc2, pi2;           /* WIN 2: counter and index of the pipelined record (for mb_write) */
    byte nopipe;             /* WIN 2: a repeat went back: stop and wait for this many more
                              * acknowledged records (the receiving PLC may read slower than
                              * records arrive) */
#if BIDI
    bool conf2, fresh2;      /* WIN 2, BIDI P9 for record cur + 1 once it is the record in
                              * flight: the own modem confirmed its block / a new telegram
                              * since its write */
#endif
#endif
SND_IDLE:
    if
    :: s_done + s_err == NT -> goto idle
    :: else -> skip
    fi;
SND_GET_CHUNK:
    /* P6: a new transfer starts with record 1 at once */
    d_step { g_next++; t = g_next; cur = 1; ctr = CTR(cur); oos = 0; otmr[S] = 0; conf = 0; fresh = 0; newrec = 1 };
#if WIN == 2
    d_step { sent2 = 0; nopipe = 0 };
#endif
#if POLLED
SND_WAIT_REQUEST:
    /* P3 polled: record 1 goes out when a request telegram arrives (P6) */
    do
    :: d_step {
            mb_read(S, nw, nc, nx, nt, ni);
            if :: nw || first -> act = A_SEND :: else -> act = A_NONE fi;
            first = 0;
            clr_read(nw, nc, nx, nt, ni)
        };
        if :: act == A_SEND -> act = A_NONE; goto send :: else -> skip fi
#if BIDI
    :: nbw[S] > 0 && S_HELD -> mb_write_other(S, ctr, t, cur)   /* MIP_Link: the built record goes along (W4: once a snapshot holds it) */
#endif
    :: rst_s > 0 -> goto restart
    :: WRST_S > 0 && S_CHANGED -> s_save(PC_REQ)     /* a periodic snapshot */
    :: wrst_s > 0 -> goto wrestart
    od;
#endif
send:
#if BIDI
    /* without W4 (LINKGATE 0): the other part's write carries the new record before its
     * snapshot, and the PLC may die right after it */
    if
    :: WRST_S > 0 && DURABLE && LINKGATE == 0 && newrec && nbw[S] > 0 ->
        mb_write_other(S, ctr, t, cur);
        if :: wrst_s > 0 -> goto wrestart :: skip fi
    :: skip
    fi;
#endif
    /* W1: the record's first write only after a snapshot that holds it (and the
     * acknowledgement of the one before) */
    if :: WRST_S > 0 && DURABLE && newrec -> s_save(PC_SEND) :: else -> skip fi;
    newrec = 0;
    mb_write(S, ctr, 0, t, cur);
#if WIN == 2
    d_step { ahead = 0; sconf = 0 };  /* P27: a repeat goes back to the oldest unacknowledged
                              * record; an acknowledgement of the one after it still counts (sent2) */
#endif
SND_WAIT_ACK:
    /* A read decides (act), and the decision is carried out by the next step, in which no
     * other branch is enabled (act != A_NONE). A read that decides nothing leaves no step
     * behind it: a dispatch after the d_step would be a step of its own, invisible to the
     * other processes and to the properties (bidi/ours-ours/spont/up+rst-rcv: 5.19 M ->
     * 4.99 M states for this one, 3.21 M with the receiver's acknowledgement step below). */
    do
    :: act == A_DONE -> act = A_NONE; goto SND_DONE
    :: act == A_NEXT || act == A_SEND -> act = A_NONE; goto send
    :: act == A_RESET || act == A_OOS -> act = A_NONE; goto SND_ERROR
    :: act == A_NONE && !(!POLLED && !rnew[S] && tmr[S] >= TT && SCANREAD) ->
        d_step {
            mb_read(S, nw, nc, nx, nt, ni);
            nw = nw || first; first = 0;     /* nw: a new telegram (section 1) */
            rd = 1;
#if BIDI
            /* P9: bit 4 clear in a read after the write: the block reached the peer's modem */
            if :: !pend[S] -> conf = 1 :: else -> skip fi;
            if :: nw -> fresh = 1 :: else -> skip fi;
#endif
            if :: cur == 1 -> prev = 0 :: else -> prev = CTR(cur - 1) fi;
            act = A_NONE;
#if WIN == 2
            if :: !pend[S] -> sconf = 1 :: else -> skip fi;
#if BIDI
            if :: ahead && !pend[S] -> conf2 = 1 :: else -> skip fi;   /* the block is cur + 1's */
            if :: sent2 && nw -> fresh2 = 1 :: else -> skip fi;
#endif
#endif
            if
#if WIN == 2
#if BIDI
            :: sent2 && nc == CTR(cur + 1) && ((fresh2 && conf2) || (PIPE_P9 == 0 && (fresh2 || PIPE_FRESH == 0))) ->
#else
            :: sent2 && nc == CTR(cur + 1) && (nx == 0 || nx == CHK(t, cur + 1) || P8_MODE == 1) ->
#endif
                /* P27: the pipelined record is acknowledged, and with it the one before (the
                 * receiver accepts only the next number) */
                oos = 0; otmr[S] = 0; ahead = 0; sent2 = 0;
#if BIDI
                conf = 0; fresh = 0; conf2 = 0; fresh2 = 0;
#endif
                if :: nopipe > 1 -> nopipe = nopipe - 2 :: else -> nopipe = 0 fi;
                if
                :: cur + 1 == NREC -> act = A_DONE
                :: else -> act = A_NEXT; cur = cur + 2; ctr = CTR(cur); newrec = 1
                fi
#if BIDI
            :: sent2 && nc == CTR(cur + 1) && !((fresh2 && conf2) || (PIPE_P9 == 0 && (fresh2 || PIPE_FRESH == 0))) ->
                /* the pipelined record's number, not counted yet (PIPE_FRESH: no telegram
                 * since its write): in step, the sender waits */
                oos = 0; otmr[S] = 0
#endif
#endif
#if BIDI
            :: nc == ctr && fresh && (conf || P9_MODE == 1) ->
#else
            :: nc == ctr && (nx == 0 || nx == CHK(t, cur) || P8_MODE == 1) ->
#endif
                /* P8: the acknowledgement of the record in flight counts */
                oos = 0; otmr[S] = 0;
#if WIN == 2
                if :: nopipe > 0 -> nopipe-- :: else -> skip fi;
                if
                :: cur == NREC -> act = A_DONE
                :: ahead -> cur++; ctr = CTR(cur); ahead = 0; sent2 = 0   /* P27: the next one is on its way already */
#if BIDI
                    ; conf = conf2; fresh = fresh2; conf2 = 0; fresh2 = 0   /* P9 now for that one */
#endif
                :: else -> act = A_NEXT; cur++; ctr = CTR(cur); conf = 0; fresh = 0; newrec = 1; sent2 = 0   /* P25 */
#if BIDI
                    ; conf2 = 0; fresh2 = 0
#endif
                fi
#else
                if
                :: cur == NREC -> act = A_DONE
                :: else -> act = A_NEXT; cur++; ctr = CTR(cur); conf = 0; fresh = 0; newrec = 1   /* P25 */
                fi
#endif
#if BIDI
            :: nc == ctr && !(fresh && (conf || P9_MODE == 1)) ->
                /* P9 not yet (no own-modem confirmation, or no telegram since the write): the
                 * number is the record in flight, so it is in step (P11); the sender waits
                 * (MIP_Sender: xAckMatch) and repeats on its timer once the confirmation was
                 * seen (SCANREAD); polled: this request is not answered with a repeat (P3:
                 * the modem sends the unconfirmed block again itself; with a telegram, P9
                 * lacks only the confirmation here) */
                oos = 0; otmr[S] = 0
#endif
            :: cur > 1 && nc == 0 -> act = A_RESET                   /* P12 peer reset */
            :: (cur == 1 && (nc == 0 || nc == LAST)) || (cur > 1 && nc == prev) ->
                /* P7 / P3: the previous acknowledgement; polled: a request, repeat */
                oos = 0; otmr[S] = 0;
                if :: POLLED && nw -> act = A_SEND :: else -> skip fi
            :: else ->
                /* P11 out of step: neither the record in flight nor the previous one */
                if
                :: !oos -> oos = 1; otmr[S] = 1
                :: oos && otmr[S] >= OT -> act = A_OOS
                :: else -> skip
                fi;
                if :: act == A_NONE && POLLED && nw -> act = A_SEND :: else -> skip fi
            fi;
            prev = 0;
            clr_read(nw, nc, nx, nt, ni)
        };
#if WIN == 2
    :: act == A_NONE && !POLLED && !rnew[S] && tmr[S] >= TT && SCANREAD ->   /* P3 spontaneous repeat */
        d_step {
            rd = 0;
            if :: sent2 && !PIPE_KEEP -> nopipe = PIPE_CLOSE :: else -> skip fi   /* P27: the window closes */
        };
        goto send
    :: act == A_NONE && !ahead && nopipe == 0 && sconf && (cur >= 2 || PIPE_FIRST) && (cur + 1 < NREC || (PIPE_LAST && cur < NREC)) ->
        /* P27: record cur reached the peer's modem; the next one goes up before the
         * acknowledgement. Not the last record (a receiver takes 16#FFFF after any number),
         * not before record 1 was acknowledged (a stale acknowledgement 2 of an earlier
         * session would pass for the pipelined record 2) */
        d_step { pc2 = CTR(cur + 1); pi2 = cur + 1 };
        /* W1 for the pipelined record: its first write only after a snapshot holds the
         * sender with it built (a rollback then writes it again: PC_PIPE) */
        if :: WRST_S > 0 && DURABLE && PIPEGATE -> s_save(PC_PIPE) :: else -> skip fi;
pipe:
        mb_write(S, pc2, 0, t, pi2);
        d_step { ahead = 1; sent2 = 1; sconf = 0; pc2 = 0; pi2 = 0
#if BIDI
            ; conf2 = 0; fresh2 = 0
#endif
        }
#else
    :: act == A_NONE && !POLLED && !rnew[S] && tmr[S] >= TT && SCANREAD -> rd = 0; goto send   /* P3 spontaneous repeat */
#endif
#if BIDI && WIN == 2
    :: act == A_NONE && nbw[S] > 0 && !ahead -> mb_write_other(S, ctr, t, cur)   /* the other stream's write re-sends the record */
    :: act == A_NONE && nbw[S] > 0 && ahead ->                         /* P27: the newest record written */
        d_step { pc2 = CTR(cur + 1); pi2 = cur + 1 };
        mb_write_other(S, pc2, t, pi2);
        d_step { pc2 = 0; pi2 = 0 }
#elif BIDI
    :: act == A_NONE && nbw[S] > 0 && S_HELD -> mb_write_other(S, ctr, t, cur)   /* the other stream's write re-sends the record */
#endif
    :: act == A_NONE && rst_s > 0 -> goto restart
    :: act == A_NONE && WRST_S > 0 && S_CHANGED -> s_save(PC_ACK)     /* a periodic snapshot */
    :: act == A_NONE && wrst_s > 0 -> goto wrestart
    od;
SND_DONE:
    app_sent(t);
    goto SND_IDLE;
SND_ERROR:
    printf("@ sender SND_ERROR\n");
    d_step { app_failed(t); oos = 0; otmr[S] = 0 };
    goto SND_IDLE;
restart:
    printf("@ sender PLC restarts\n");
    d_step { rst_s--; sabort = sabort | (1 << t); first = 1; oos = 0; otmr[S] = 0; im_reset(S) };
    goto SND_IDLE;
wrestart:
    /* a warm restart: everything since the last snapshot is lost (kill -9); the timers start
     * again; the write a restored handshake still asks for may or may not be repeated */
    printf("@ sender PLC warm restart: back to the snapshot (pc %d, record %d of t%d)\n", ss_pc, ss_cur, ss_t);
    d_step {
        wrst_s--;
        cur = ss_cur; t = ss_t; ctr = ss_ctr; conf = ss_conf; fresh = ss_fresh; first = ss_first;
        rd = ss_rd; g_next = ss_gnext; s_done = ss_sdone; s_err = ss_serr; s_fin = ss_sfin;
        oos = 0; otmr[S] = 0; newrec = 0; im_reset(S)
    };
#if WIN == 2
    d_step {
        if
        :: PIPERESTORE -> ahead = ss_ahead; sent2 = ss_sent2; sconf = ss_sconf; nopipe = ss_nopipe
        :: else -> ahead = 0; sent2 = 0; sconf = 0; nopipe = 0   /* variant: not restored */
        fi
#if BIDI
        ; conf2 = 0; fresh2 = 0
#endif
    };
#endif
    if
    :: ss_pc == PC_IDLE -> goto SND_IDLE
#if WIN == 2
    /* the pipelined record built (W1): written again, the sender waits for acknowledgements */
    :: ss_pc == PC_PIPE -> d_step { pc2 = CTR(cur + 1); pi2 = cur + 1 }; goto pipe
    /* the restored handshake repeats the write of the pipelined record, the newest written */
    :: ss_pc == PC_ACK && ahead ->
        d_step { pc2 = CTR(cur + 1); pi2 = cur + 1 };
        mb_write(S, pc2, 0, t, pi2);
        d_step { pc2 = 0; pi2 = 0; sconf = 0 };
        goto SND_WAIT_ACK
#endif
    :: ss_pc == PC_SEND -> newrec = 1; goto send
    :: ss_pc == PC_ACK -> goto send
    :: ss_pc == PC_ACK -> goto SND_WAIT_ACK
#if POLLED
    :: ss_pc == PC_REQ -> goto SND_WAIT_REQUEST
#endif
    fi;
idle:
    do
    :: d_step { mb_read(S, nw, nc, nx, nt, ni); clr_read(nw, nc, nx, nt, ni); first = 0 }
#if BIDI
    /* an idle MIP_Link sends record 0 (W4: once a snapshot holds the idle sender; a rollback
     * to its last record after the peer saw 0 and forgot the transfer would send 16#FFFF to a
     * receiver that takes it for a one-record transfer) */
    :: nbw[S] > 0 && S_IDLE_HELD -> mb_write_other(S, 0, 0, 0)
    :: WRST_S > 0 && ss_pc != PC_IDLE -> s_save(PC_IDLE)   /* the snapshot it asks for */
#endif
    :: wrst_s > 0 -> goto wrestart
    od
}

ACTIVE_OurReceiver proctype OurReceiver() {
    byte L, Lchk, c, nc, nx, nt, ni, act;
    byte oldchk;             /* P19: check value of an old 16#FFFF found as the first block */
    bool nw, first = 1, uoos;
#if SPLITREAD
    byte dnum;               /* MIP_Internal_ReadDecoder: a changed number is a new telegram too (SPLITREAD only) */
#endif
    bool sempty;             /* P19: a read since xEnable showed the area empty (count 0) */
    bool nolone;             /* P19: no lone 16#FFFF until a record 1 was accepted */
RCV_WAIT_FIRST:
    skip;
    /* P23: acknowledge 0 once on start */
    d_step { L = 0; Lchk = CHK0; uoos = 0; otmr[R] = 0 };
    mb_write(R, 0, ECHO(0, CHK0), 0, 0);
RCV_IN_TRANSFER:          /* also RCV_COMPLETE (L = 16#FFFF): one loop, L tells them apart */
    /* as in the sender: the decision of a read (act) is the next step; the acknowledgement's
     * write is one step with the snapshot before it (W2), which no other process reads */
    do
    :: act == A_ACK ->
#if BIDI && LINKGATE == 0
        /* without W4: the other part's write carries the new acknowledgement before its
         * snapshot, and the PLC may die right after it */
        if
        :: WRST_R > 0 && DURABLE && nbw[R] > 0 && !(sr_L == L && sr_Lchk == Lchk) ->
            mb_write_other(R, L, 0, 0);
            if :: wrst_r > 0 -> act = A_NONE; goto rwarm :: skip fi
        :: skip
        fi;
#endif
        d_step {
            act = A_NONE;
            /* W2: an acknowledgement only after a snapshot that holds what it confirms */
            if :: WRST_R > 0 && DURABLE -> r_save() :: else -> skip fi;
            mb_write(R, L, ECHO(L, Lchk), 0, 0)
        }
    :: act == A_NONE && !(POLLED && !rnew[R] && tmr[R] >= TT) ->
        d_step {
            mb_read(R, nw, nc, nx, nt, ni);
            c = CHK(nt, ni);
            act = A_NONE;
            if
#if BIDI
            :: nc == 0 && (nw || first) && L != 0 ->
                /* P16 record 0 of an idle MIP_Link: an open transfer fails
                 * (MIP_ERR_SENDER_RESET), a complete one is forgotten; acknowledge 0 */
                sempty = 1;
                if :: L != LAST -> app_drop(1) :: else -> skip fi;
                L = 0; Lchk = CHK0; uoos = 0; otmr[R] = 0; act = A_ACK
#endif
            :: nc == 0 -> sempty = 1         /* an empty area (count 0), or record 0 with nothing open */
            :: nc != 0 && !(nw || first || DNUM_NEW(nc)) -> skip   /* no telegram */
            :: RFIRST_MODE == 1 && nc != 0 && first && !nw -> first = 0   /* variant: the first read's old block never counts */
            :: else ->
                if
                :: first && nc == LAST && (!nw || !sempty) ->
                    oldchk = c   /* P19: an old 16#FFFF as the first block, and its copies */
                :: first && nc != LAST ->
                    nolone = 1   /* P19: a sender was mid-transfer when this receiver started */
                :: else -> skip
                fi;
                if
                :: nc == L && c == Lchk ->
                    /* P17 duplicate: acknowledge again */
                    uoos = 0; otmr[R] = 0; act = A_ACK
                :: nc == 1 && !(L == 1 && c == Lchk) ->
                    /* P15 / P18 (RCV_WAIT_PROCESSED): record 1 starts a new transfer; an
                     * open one fails with MIP_ERR_SENDER_RESET */
                    if :: L != 0 && L != LAST -> app_drop(1) :: else -> skip fi;
                    app_record(nt, ni); L = 1; Lchk = c; uoos = 0; otmr[R] = 0; act = A_ACK;
                    nolone = 0
                :: nc != 1 && L != 0 && L != LAST && (nc == L + 1 || nc == LAST) ->
                    /* P15 the next record (RCV_WAIT_PROCESSED) */
                    app_record(nt, ni);
                    if :: nc == LAST -> app_complete() :: else -> skip fi;
                    L = nc; Lchk = c; uoos = 0; otmr[R] = 0; act = A_ACK
                :: nc == LAST && ((P19_MODE != 1 && P19_MODE != 2 && L == 0) || (P19_MODE != 2 && L == LAST && c != Lchk)) && !nolone && c != oldchk ->
                    /* P19 a lone 16#FFFF: a complete one-record transfer, unless it may be the
                     * tail of a transfer whose start this receiver lost */
                    app_record(nt, ni); app_complete(); L = LAST; Lchk = c; uoos = 0; otmr[R] = 0;
                    act = A_ACK
                :: else ->
                    /* P20 unexpected: ignored, the last acknowledgement repeated; P21 */
                    if
                    :: first && (nc == LAST || nc == 1) -> skip   /* an idle or new sender's block */
                    :: (!first || (nc != LAST && nc != 1)) && !uoos -> uoos = 1; otmr[R] = 1   /* a first block mid-transfer counts too */
                    :: !first && uoos && otmr[R] >= OT -> assert(!WARMONLY || WARMFAIL || R_OOS_WARMOK); r_stuck = 1; printf("@ receiver xError PEER_OUT_OF_STEP\n")
                    :: else -> skip
                    fi;
                    act = A_ACK
                fi
            fi;
            if :: nc != 0 -> first = 0 :: else -> skip fi;   /* the first block read has a count */
#if SPLITREAD
            if :: nc != 0 -> dnum = nc :: else -> skip fi;
#endif
            c = 0;
            clr_read(nw, nc, nx, nt, ni)
        };
    :: act == A_NONE && POLLED && !rnew[R] && tmr[R] >= TT -> mb_write(R, L, ECHO(L, Lchk), 0, 0)   /* P3 polled */
#if BIDI
    :: act == A_NONE && nbw[R] > 0 && R_HELD -> mb_write_other(R, L, 0, 0)      /* the other stream's write carries L (W4: once a snapshot holds it) */
#endif
    :: act == A_NONE && uoos && otmr[R] >= OT && !r_stuck ->
        /* P21 by time: the bound passed with only unexpected numbers and no telegram in step
         * (a static-mode sender never sends its unchanged block again) */
        assert(!WARMONLY || WARMFAIL || R_OOS_WARMOK);
        r_stuck = 1; printf("@ receiver xError PEER_OUT_OF_STEP (bound)\n")
    :: act == A_NONE && rst_r > 0 ->
        printf("@ receiver PLC restarts\n");
        d_step { rst_r--; app_drop(1); first = 1; sempty = 0; nolone = 0; oldchk = 0; im_reset(R) };
#if SPLITREAD
        dnum = 0;
#endif
        goto RCV_WAIT_FIRST
    :: act == A_NONE && WRST_R > 0 && R_CHANGED -> r_save()     /* a periodic snapshot */
    :: act == A_NONE && wrst_r > 0 -> goto rwarm
#if SPLITREAD
    :: act == A_NONE && wrst_r > 0 ->
        /* killed while a read's answer was on the line: that read took bit 0 */
        d_step { rnew[R] = 0; printf("@ receiver PLC reads; killed before the answer arrives (bit 0 taken)\n") };
        goto rwarm
#endif
    od;
rwarm:
    /* a warm restart: block and store back to the last snapshot (kill -9); no
     * acknowledgement 0 (xEnable did not rise); the restored handshake may repeat the
     * write of the acknowledgement */
    printf("@ receiver PLC warm restart: back to the snapshot (L %d)\n", sr_L);
    d_step {
        wrst_r--;
        L = sr_L; Lchk = sr_Lchk; oldchk = sr_oldchk; first = sr_first; sempty = sr_sempty;
        nolone = sr_nolone; a_t = sr_at; a_i = sr_ai; compl = sr_compl; r_err = sr_rerr;
        uoos = 0; otmr[R] = 0; im_reset(R)
    };
#if SPLITREAD
    dnum = sr_dnum;
#endif
    if :: mb_write(R, L, ECHO(L, Lchk), 0, 0) :: skip fi;
    goto RCV_IN_TRANSFER
}
