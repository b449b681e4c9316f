/* The SIPROTEC event-recorder handshake at the outstation (issue 35; docs/chain.md "The
 * relay" and "The reader (MIP_SoeReader)"): a relay's recorder, MIP_SoeReader and the logger
 * it stores into. Property: the handshake (acknowledge after store) loses nothing at the
 * outstation - every event the relay recorded ends in the logger, in order, with no gap;
 * exactly once unless the PLC restarts cold.
 *
 * One Modbus transaction is one atomic step (the relay answers one request at a time); its
 * answer may be lost (LOSS of them), after the relay acted on it. The PLC may restart (RST
 * times): cold (its state lost, the logger's durable store kept) or warm (WARM=1: the block
 * and the logger come back as the last snapshot had them; the snapshot handshake of
 * st_lib/README.md "Warm restarts").
 *
 * Variants that must fail (model/run.py):
 *   ACK_EARLY=1  acknowledge a read before its entries are stored: a cold restart between the
 *                acknowledgement and the store loses them (LOST)
 *   NOGATE=1     warm restarts, but the acknowledgement does not wait for a snapshot that
 *                holds the stored entries: the PLC comes back with an older store (LOST)
 *   NODETECT=1   relay restarts (RRST), and the reader does not take a restarted relay's
 *                first number: it rejects its reads for good (STUCK)
 *   RR_ANY=1 VERIFY=0
 *                the relay may restart while the reader holds an open read numbered 1 (or
 *                its last snapshot does), and the reader acknowledges it without reading it
 *                again first (the block before the verify read): its acknowledgement
 *                (1 + 256 n) is taken by the restarted relay for its own first read and deletes
 *                up to n new entries nobody read (LOST). [S5] 5.2.5 carries no restart marker.
 *   RR_ANY=1 VWIN=0
 *                the verify read (VERIFY=1), but the relay may restart AND record a new entry
 *                between the verify read's answer and the acknowledgement's arrival: LOST. The
 *                verify read closes the window only down to that interval (one Modbus round
 *                trip and a scan, docs/chain.md "Restarts"): what the fix relies on.
 *
 * The verify read (VERIFY=1, default; MIP_SoeReader's state MIP_SOE_VERIFY): before the
 * acknowledgement of an open read numbered 1 - the only number a restarted relay reaches
 * without an acknowledgement of ours - the reader reads the recorder again, after every entry
 * of the read is stored, and writes the acknowledgement only if that read shows the open read
 * unchanged (number, blocks, entries); else the read is judged as any other (a restarted relay
 * taken up). Nothing else happens between the verify read and the acknowledgement (the block
 * starts the write in the call that evaluates the verify read). VWIN=1 (default) is the timing
 * assumption, encoded: the relay does not restart and then record an entry between the two.
 * With RR_ANY=1 and both defaults the model holds (configurations soe-verify/*).
 *
 * The acknowledgement is two steps: the block raises the write, the relay acts on it when it
 * arrives. The runtime may take a periodic snapshot in between (WARM). RDETECT=1 (default):
 * a PLC restored from such a snapshot sees its restart (MIP_SoeReader: wSnapshots goes down,
 * plcrt's count starts again from 0) and ends that write as failed, so a new read (for a read
 * numbered 1 the verify read) decides. A PLC restart ends the VWIN interval: the relay may
 * restart and record before a restored write arrives.
 *   RR_ANY=1 WARM=1 RDETECT=0
 *                the restored write goes out after the restart without a new verify read:
 *                LOST (configuration soe-verify-inflight/warm).
 *
 * Relay restarts (RRST of them; docs/chain.md "What restarts do", our choice): the recorder is
 * emptied and the sequence number goes to 0; what it held is the relay's own loss (events up
 * to `lo` not stored are excused). The reader judges a read's number as MIP_SoeReader does
 * (known/lseq: only the open read, its successor or, with none open, the successor of the last
 * number) and takes a read with blocks and sequence number 1 that it would reject, seen twice
 * in a row with the same content, as a restarted relay: it drops its open read (what it stored
 * of it stays) and takes the new one. Every other rejected read stays rejected (the block: a
 * named error after tRetryTimeout); STUCK bounds the rejected reads in a row.
 *
 * Sizes: N events, BLK message blocks per read (3 in the relay; 2 gives the same cases with
 * fewer states: a read of several, a partial one), sequence numbers of SEQB bits.
 */
#ifndef N
#define N 4
#endif
#ifndef BLK
#define BLK 2
#endif
#ifndef SEQB
#define SEQB 2
#endif
#ifndef LOSS
#define LOSS 2
#endif
#ifndef RST
#define RST 1
#endif
#ifndef WARM
#define WARM 0
#endif
#ifndef ACK_EARLY
#define ACK_EARLY 0
#endif
#ifndef NOGATE
#define NOGATE 0
#endif
#ifndef RRST
#define RRST 0
#endif
#ifndef NODETECT
#define NODETECT 0
#endif
#ifndef RR_ANY
#define RR_ANY 0
#endif
#ifndef VERIFY
#define VERIFY 1
#endif
#ifndef VWIN
#define VWIN 1
#endif
#ifndef RDETECT
#define RDETECT 1
#endif
/* the names of the properties, as in env.pml: -DSEEK=K_<name> (model/run.py's search for one
 * documented weakness) switches the others off */
#define K_GAP 1
#define K_DUP_ORDER 3
#define K_LOST 4
#define K_STUCK 5
#ifndef SEEK
#define SEEK 0
#endif
bool GAP = (SEEK != 0 && SEEK != K_GAP), DUP_ORDER = (SEEK != 0 && SEEK != K_DUP_ORDER),
     LOST = (SEEK != 0 && SEEK != K_LOST), STUCK = (SEEK != 0 && SEEK != K_STUCK);
#define TOP ((1 << SEQB) - 1)
#define NEXT(s) ((s) >= TOP -> 1 : (s) + 1)

/* ---- the relay's recorder: entries head .. gen (ids 1..N in event order) ---- */
byte gen = 0;              /* events recorded so far */
byte head = 1;             /* oldest entry not acknowledged */
byte offer = 0;            /* entries offered: head .. head + offer - 1 */
bool offer_read = false;   /* a read showed them: they stay until acknowledged */
byte seq = 0;              /* SOE_Control's sequence number */

inline refresh() {
    /* docs/chain.md: a set no read has shown yet may grow to BLK; a new set, the next number */
    if
    :: !offer_read ->
        if
        :: offer == 0 && gen >= head -> seq = NEXT(seq)
        :: else -> skip
        fi;
        offer = (gen - head + 1 > BLK -> BLK : gen - head + 1)
    :: else -> skip
    fi
}

/* ---- the logger's store (durable): the highest id stored in order ---- */
byte last = 0;
byte lo = 0;               /* events up to lo were in a relay that restarted: not stored, its loss */
byte rrst = 0;
#define FLOOR (last > lo -> last : lo)

/* ---- MIP_SoeReader: the open read and how many of its entries were stored ---- */
bool open = false;
byte oseq, ohead, on, stored;
bool acked_early = false;  /* ACK_EARLY: this open read's acknowledgement is done */
bool unsaved = false;      /* a change no snapshot holds yet */
bool known = false;        /* lseq is known (xKnown) */
byte lseq = 0;             /* the number of the last read (wLastSeq) */
bool cand = false;         /* the last read was a rejected number 1 with blocks: chead, con */
byte chead, con;
byte rej = 0;              /* rejected reads in a row */
byte rrdet = 0;            /* relay restarts detected (udiRelayRestarts) */
bool verified = false;     /* VERIFY: a read after the last store showed the open read unchanged;
                              only the acknowledgement follows (not in a snapshot) */
bool win = false;          /* from that verify read to the acknowledgement's arrival, no PLC
                              restart in between: the interval VWIN is about */
bool rr_win = false;       /* the relay restarted in that interval (VWIN) */
bool inflight = false;     /* the acknowledgement is written (xWriteReq), not yet at the relay */
bool s_inflight = false;   /* ... as the last snapshot holds it */
/* the last snapshot (WARM): the block's state and the logger's store together */
bool s_open = false;
byte s_oseq, s_ohead, s_on, s_stored, s_last;
bool s_acked = false;
bool s_known = false;
byte s_lseq = 0;

byte losses = 0, restarts = 0;

inline store_one() {
    /* the logger stores entry ohead + stored (the scan it is shown; xEntryStored) */
    d_step {
        assert(ohead + stored <= FLOOR + 1 || GAP);    /* an entry skipped */
#if WARM || !RST
        assert((ohead + stored > last && ohead + stored <= FLOOR + 1) || DUP_ORDER); /* exactly once, in order */
#endif
        if
        :: ohead + stored > last -> last = ohead + stored
        :: else -> skip                                 /* a duplicate after a cold restart */
        fi;
        stored++;
        unsaved = true;
        printf("@ store %d\n", ohead + stored - 1)
    }
}

inline ack() {
    /* the write of SOE_Control: seq + 256 n; the relay deletes n and raises the number */
    atomic {
        verified = false; win = false; rr_win = false; inflight = false;  /* taken, refused or
                                                 its answer lost: a read decides */
        if
        :: open && oseq == seq && offer > 0 && (ACK_EARLY -> on : stored) <= offer ->
            head = head + (ACK_EARLY -> on : stored);
            offer = 0;
            offer_read = false;
            refresh();
            printf("@ ack seq %d n %d: taken\n", oseq, (ACK_EARLY -> on : stored));
            if
            :: losses < LOSS -> losses++; printf("@ ... its answer lost\n")
            :: true ->
                if
                :: ACK_EARLY -> acked_early = true
                :: else -> open = false; unsaved = true
                fi
            fi
        :: else -> printf("@ ack seq %d refused (exception 03)\n", oseq)
        fi
    }
}

inline ack_send() {
    /* the block raises the write (the relay acts on it when it arrives: ack()) */
    atomic { verified = false; inflight = true; printf("@ ack seq %d n %d: written\n", oseq, stored) }
}

inline take_new() {
    verified = false;
    open = true; oseq = seq; ohead = head; on = offer; stored = 0; known = true; lseq = seq;
    acked_early = false; unsaved = true; printf("@ read: seq %d (%d entries)\n", seq, offer)
}

inline read_and_judge() {
    /* one FC3 of 40601..40626 and the block's judgement (docs/chain.md "How a read is
     * judged"; the model's reads are never stale: a read follows the write it may decide) */
    atomic {
        offer_read = offer_read || offer > 0;
        verified = false;
        if
        :: losses < LOSS -> losses++; printf("@ read: answer lost\n")
        :: true ->
            if
            :: offer == 0 && seq == 0 ->
                open = false; unsaved = true; known = true; lseq = 0; rej = 0; cand = false
            :: offer == 0 && seq != 0 && open && seq == oseq ->
                open = false; unsaved = true; rej = 0; cand = false  /* acknowledged, answer lost */
            :: offer == 0 && seq != 0 && !(open && seq == oseq) && (!known || seq == lseq) ->
                known = true; lseq = seq; rej = 0; cand = false
            :: open && offer > 0 && seq == oseq && head == ohead && offer == on ->
                known = true; lseq = oseq; rej = 0; cand = false;     /* the open read again */
                verified = (stored == on && !(WARM && !NOGATE && unsaved))  /* the verify read:
                    after the last store, with the snapshot that holds it (the block: NOT xUnsaved) */
                win = verified;
                printf("@ read: the open read again (seq %d, verified %d)\n", oseq, verified)
            :: offer > 0 && ((open && seq == NEXT(oseq)) || (!open && (!known || seq == NEXT(lseq)))) ->
                /* a new read (when one was open: its acknowledgement was taken) */
                take_new(); rej = 0; cand = false
            :: else ->
                /* rejected (out of sequence, changed); a number 1 with blocks twice the same:
                 * a restarted relay */
                if
                :: !NODETECT && offer > 0 && seq == 1 && cand && chead == head && con == offer ->
                    rrdet++; printf("@ read: relay restart detected\n");
                    take_new(); rej = 0; cand = false
                :: else ->
                    cand = offer > 0 && seq == 1; chead = head; con = offer;
                    rej++; printf("@ read: rejected (seq %d)\n", seq);
                    assert(rej < 3 || STUCK)            /* the block: an error it never leaves */
                fi
            fi
        fi
    }
}

inline relay_restart() {
    /* a power cycle of the relay: its recorder empty, its number 0 (our choice) */
    atomic {
        rrst < RRST && (RR_ANY || !((open && oseq == 1) || (WARM && s_open && s_oseq == 1))) ->
        rrst++; lo = gen; head = gen + 1; offer = 0; offer_read = false; seq = 0;
        rr_win = win;
        printf("@ relay restart\n")
    }
}

active proctype Events() {
    do
    :: atomic { gen < N && !(VWIN && rr_win) -> gen++; refresh(); printf("@ event %d\n", gen) }
    :: relay_restart()
    :: gen == N && rrst == RRST -> break
    od
}

active proctype Reader() {
end:
    do
#if ACK_EARLY
    :: (!open || !acked_early) -> read_and_judge()     /* not while handing over */
    :: open && !acked_early -> ack()
    :: open && acked_early && stored < on -> store_one()
    :: atomic { open && acked_early && stored == on -> open = false }
#else
    :: (!open || stored == on) && !verified && !inflight -> read_and_judge()  /* MIP_SOE_READ, _RETRY, _VERIFY */
    :: open && stored < on -> store_one()
    :: (open && stored == on && on > 0 && !inflight && (NOGATE || WARM == 0 || !unsaved)
        && (!VERIFY || oseq != 1 || verified)) -> ack_send()
    :: inflight -> ack()
#endif
#if WARM
    /* asked for (unsaved), or the runtime's periodic one while a write is in flight */
    :: atomic { (unsaved || (inflight && !s_inflight)) ->
                s_open = open; s_oseq = oseq; s_ohead = ohead; s_on = on;
                s_stored = stored; s_last = last; s_acked = acked_early; unsaved = false;
                s_known = known; s_lseq = lseq; s_inflight = inflight;
                printf("@ snapshot (acknowledgement in flight: %d)\n", inflight) }
#endif
    :: atomic { restarts < RST ->
        restarts++;
#if WARM
        open = s_open; oseq = s_oseq; ohead = s_ohead; on = s_on; stored = s_stored;
        last = s_last; acked_early = s_acked; unsaved = false;
        known = s_known; lseq = s_lseq; cand = false; rej = 0;
        verified = false; win = false; rr_win = false;
        inflight = s_inflight && !RDETECT;   /* RDETECT: a restored write ends as failed */
        printf("@ PLC warm restart\n")
#else
        open = false; stored = 0; acked_early = false;
        known = false; cand = false; rej = 0;   /* xEnable rises again: any number */
        verified = false; win = false; rr_win = false; inflight = false;
        printf("@ PLC cold restart\n")
#endif
       }
    od
}

/* Nothing lost: once every event is recorded and acknowledged and nothing is open, the
 * logger holds them all. */
active proctype Check() {
end:
    atomic { gen == N && rrst == RRST && head > N && !open -> assert(last == N || lo == N || LOST) }
}
