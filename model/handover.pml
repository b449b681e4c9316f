/* The hand-over at the central (issue 35): the central PLC acknowledges a record over the
 * radio only after the control system took it (MIP_Receiver's xAckByCaller fed by
 * MIP_UnicosEvents' xRecordProcessed, docs/chain.md "The control system, push (UNICOS)").
 *
 * A small model of its own, beside mip.pml (which has the record protocol in detail): an
 * outstation that keeps each record until its acknowledgement and then deletes it (the relay's
 * entries are gone from the outstation then), a lossy radio both ways, the central with one
 * record in hand, the control system's driver behind a Modbus link, and restarts of the
 * central between receipt and hand-over:
 *   COLD: the central's memory is lost (the record in hand, the number it acknowledged last);
 *         it then takes whatever record comes next (ack 0 and the transfer sent again, in the
 *         real protocol: the same records again, duplicates reported).
 *   WARM: the central keeps its state (retained); a Modbus write under way is lost with its
 *         answer and made again.
 * What must hold: every record the outstation deleted has reached the control system (LOST,
 * checked when everything is quiet) and the outstation finishes (the ltl claim, under weak
 * fairness). Without restarts nothing reaches the control system twice (DUP).
 * Must fail: ACK_FIRST=1 (the central acknowledges on receipt, hands over afterwards) with a
 * cold restart loses the record in hand: the outstation deleted it, the control system never
 * got it.
 *
 * Defines: N records (default 3); RST restarts of the central (0, 1, 2); COLD 1 / 0 (warm);
 * ACK_FIRST 1: acknowledge before the hand-over; MAXLOSS telegrams the radio may lose
 * (default 2); SEEK (model/run.py: the one property a must-fail search looks for). */

#ifndef N
#define N 3
#endif
#ifndef RST
#define RST 0
#endif
#ifndef COLD
#define COLD 1
#endif
#ifndef ACK_FIRST
#define ACK_FIRST 0
#endif
#ifndef MAXLOSS
#define MAXLOSS 2
#endif

/* Never set: each names the property in the text spin prints for a violated assertion
 * (as env.pml); -DSEEK=K_<name> sets every other one. */
#define K_LOST 4
#define K_DUP_ORDER 3
#ifndef SEEK
#define SEEK 0
#endif
bool LOST = (SEEK != 0 && SEEK != K_LOST), DUP_ORDER = (SEEK != 0 && SEEK != K_DUP_ORDER);

#define UNKNOWN 255

chan up = [1] of { byte };        /* radio: outstation -> central, the record's number */
chan down = [1] of { byte };      /* radio: central -> outstation, the acknowledgement */
chan mbreq = [1] of { byte };     /* Modbus: central -> driver, the record's events */
chan mbresp = [1] of { byte };    /* Modbus: driver -> central, the positive response */

byte acked = 0;                   /* outstation: records acknowledged (and deleted) */
byte delivered[N + 1];            /* control system: how often each record arrived */
byte inhand = 0;                  /* central: the record received, not yet handed over */
bool sent = false;                /* central: its write to the driver is under way */
byte lastack = 0;                 /* central: the number it acknowledged last */
byte restarts = 0;
byte losses = 0;

ltl done { <> (acked == N) }

active proctype Outstation() {
  byte a;
  do
  :: acked < N && nfull(up) && empty(down) -> up!(acked + 1);   /* (again) the oldest record not
                                                       acknowledged; an acknowledgement waiting is read first */
     printf("@ outstation sends record %d\n", acked + 1)
  :: down?a ->
     if
     :: a == acked + 1 -> acked++;
        printf("@ outstation: record %d acknowledged, deleted\n", a)
     :: else
     fi
  :: acked == N -> break
  od
}

active proctype Radio() {         /* loses a telegram now and then */
  byte x;
  end: do
  :: losses < MAXLOSS -> atomic { up?x -> losses++; printf("@ radio loses record %d\n", x) }
  :: losses < MAXLOSS -> atomic { down?x -> losses++; printf("@ radio loses ack %d\n", x) }
  od
}

active proctype Driver() {        /* the control system's driver: takes a frame, answers */
  byte r;
  end: do
  :: mbreq?r -> delivered[r]++;
     printf("@ control system takes record %d\n", r);
     assert(delivered[r] == 1 || RST > 0 || DUP_ORDER);   /* no restart: never twice */
     mbresp!r
  od
}

inline ack(n) {
  lastack = n;
  if
  :: nfull(down) -> down!n; printf("@ central acknowledges %d over the radio\n", n)
  :: full(down) -> skip          /* the radio is busy: the outstation sends it again */
  fi
}

active proctype Central() {
  byte r;
  end: do
  :: inhand == 0 && nempty(up) -> up?r;   /* it reads the modem when it can take a record */
     if
     :: inhand == 0 && (r == lastack + 1 || lastack == UNKNOWN) ->
        inhand = r;
        printf("@ central receives record %d\n", r);
        if
        :: ACK_FIRST -> ack(r)
        :: else
        fi
     :: lastack != UNKNOWN && r <= lastack -> ack(lastack)   /* a repeat: acknowledged again */
     :: else -> skip
     fi
  :: inhand != 0 && !sent && nfull(mbreq) -> mbreq!inhand; sent = true
  :: mbresp?r ->
     if
     :: r == inhand && sent ->
        printf("@ central: record %d handed over\n", r);
        if
        :: !ACK_FIRST -> ack(r)
        :: else
        fi;
        inhand = 0;
        sent = false
     :: else -> skip            /* the answer to a write made before a restart */
     fi
  :: restarts < RST && inhand != 0 ->   /* a restart between receipt and hand-over */
     atomic {
       restarts++;
       if
       :: mbresp?[r] -> mbresp?r   /* an answer on its way is lost with the connection */
       :: empty(mbresp) -> skip
       fi;
       sent = false;
       if
       :: COLD -> inhand = 0; lastack = UNKNOWN;
          printf("@ central PLC restarts cold: the record in hand is gone\n")
       :: !COLD -> printf("@ central PLC restarts warm: it keeps record %d\n", inhand)
       fi
     }
  od
}

active proctype Check() {         /* when all is quiet: every deleted record is at the control system */
  byte i = 1;
  atomic {
    (acked == N && inhand == 0 && empty(mbreq) && empty(mbresp)) ->
    do
    :: i <= N -> assert(delivered[i] > 0 || LOST); i++
    :: else -> break
    od
  }
}
