/* note_peers.pml: a sender and a receiver that follow only the Piciorgros note, section 2.1
 * (dynamic mode, one counter register). Two readings each, chosen with -DNS_LENIENT /
 * -DNR_LENIENT:
 *   receiver, strict:  only the next number counts (1 after 0 or 16#FFFF; n+1 or 16#FFFF
 *                      after n); its last number again is a duplicate; anything else ignored.
 *   receiver, lenient: as strict, and record 1 always starts a new transfer.
 *   sender, strict:    only the acknowledgement of the record in flight counts.
 *   sender, lenient:   as strict, and acknowledgement 0 (the receiver has nothing) in the
 *                      middle of a transfer starts the transfer again with record 1.
 * Drive (POLLED): polled = the receiver repeats its acknowledgement every TT slots and the
 * sender writes its record again on every acknowledgement that is not the one it waits for;
 * spontaneous = the sender writes its record again every TT slots, the receiver writes only
 * when a record arrived.
 * A restart (RST_S / RST_R) loses the PLC's state; the modem keeps its buffers.
 * Each scan reads the read area (one FC3) and decides in one d_step; a PLC whose repetition
 * timer expired acts on it in that scan.
 */

#ifndef NS_LENIENT
#define NS_LENIENT 0
#endif
#ifndef NR_LENIENT
#define NR_LENIENT 0
#endif

/* decisions */
#define A_NONE   0
#define A_SEND   1   /* write the record (again) */
#define A_NEXT   2   /* acknowledged: next record */
#define A_DONE   3   /* last record acknowledged */
#define A_ACK    4   /* write the acknowledgement */

ACTIVE_NoteSender proctype NoteSender() {
    byte cur, t, ctr, nc, nx, nt, ni, act;
    bool nw;
newt:
    if
    :: s_done + s_err == NT -> goto idle
    :: else -> skip
    fi;
    d_step { g_next++; t = g_next; cur = 1; ctr = CTR(cur) };
send:
    mb_write(S, ctr, 0, t, cur);
wait:
    /* the decision of a read (act) is the next step; a read that decides nothing leaves no
     * step behind it (our_peers.pml, SND_WAIT_ACK) */
    do
    :: act == A_DONE -> act = A_NONE; app_sent(t); goto newt
    :: act == A_NEXT || act == A_SEND -> act = A_NONE; goto send
    :: act == A_NONE && !(!POLLED && !rnew[S] && tmr[S] >= TT) ->
        d_step {
            mb_read(S, nw, nc, nx, nt, ni);
            if
            :: nw && nc == ctr && cur == NREC -> act = A_DONE
            :: nw && nc == ctr && cur < NREC -> act = A_NEXT; cur++; ctr = CTR(cur)
            :: NS_LENIENT && nw && nc == 0 && cur > 1 -> act = A_SEND; cur = 1; ctr = CTR(cur)
            :: POLLED && nw && nc != ctr -> act = A_SEND
            :: else -> act = A_NONE
            fi;
            clr_read(nw, nc, nx, nt, ni)
        }
    :: act == A_NONE && !POLLED && !rnew[S] && tmr[S] >= TT -> goto send
#if BIDI
    :: act == A_NONE && nbw[S] > 0 -> mb_write_other(S, ctr, t, cur)   /* note 2.2: its other stream's write */
#endif
    :: act == A_NONE && rst_s > 0 -> printf("@ sender PLC restarts\n"); rst_s--; sabort = sabort | (1 << t); goto newt
    od;
idle:
    do
    :: d_step { mb_read(S, nw, nc, nx, nt, ni); clr_read(nw, nc, nx, nt, ni) }
#if BIDI
    :: nbw[S] > 0 -> mb_write_other(S, ctr, t, cur)   /* keeps its last record */
#endif
    od
}

ACTIVE_NoteReceiver proctype NoteReceiver() {
    byte last, nc, nx, nt, ni, act;
    bool nw;
    mb_write(R, 0, 0, 0, 0);      /* the request with acknowledgement 0 */
    do
    :: act == A_ACK -> d_step { act = A_NONE; mb_write(R, last, 0, 0, 0) }
    :: act == A_NONE && !(POLLED && !rnew[R] && tmr[R] >= TT) ->
        d_step {
            mb_read(R, nw, nc, nx, nt, ni);
            act = A_NONE;
            if
            :: nw && nc != 0 && nc == last -> act = A_ACK   /* duplicate: acknowledge again */
            :: nw && nc == 1 && (last == 0 || last == LAST) ->
                app_record(nt, ni); last = 1; act = A_ACK
            :: nw && nc != 0 && last != 0 && last != LAST && (nc == last + 1 || nc == LAST) ->
                app_record(nt, ni);
                if :: nc == LAST -> app_complete() :: else -> skip fi;
                last = nc; act = A_ACK
            :: NR_LENIENT && nw && nc == 1 && last != 0 && last != LAST && last != 1 ->
                app_drop(0); app_record(nt, ni); last = 1; act = A_ACK
            :: else -> skip                             /* not expected: ignored */
            fi;
            clr_read(nw, nc, nx, nt, ni)
        }
    :: act == A_NONE && POLLED && !rnew[R] && tmr[R] >= TT -> mb_write(R, last, 0, 0, 0)
#if BIDI
    :: act == A_NONE && nbw[R] > 0 -> mb_write_other(R, last, 0, 0)
#endif
    :: act == A_NONE && rst_r > 0 -> printf("@ receiver PLC restarts\n"); rst_r--; d_step { app_drop(1) }; last = 0; mb_write(R, 0, 0, 0, 0)
    od
}
