/* mip.pml: the model checked by model/run.py. Pick the peers with -DSND=NOTE|OURS and
 * -DRCV=NOTE|OURS (see env.pml for the environment's knobs, note_peers.pml and our_peers.pml
 * for the peers). */
#define NOTE 1
#define OURS 2
#ifndef SND
#define SND NOTE
#endif
#ifndef RCV
#define RCV NOTE
#endif

/* The chosen peers are active processes; there is no init process. pan's weak fairness (-f)
 * counts every process, an ended init too: with one, bidi/ours-ours/spont/up+rst-rcv's progress
 * search took 32 s against 19 s (the same verdict); over the whole matrix about a tenth. */
#if SND == NOTE
#define ACTIVE_NoteSender active
#define ACTIVE_OurSender
#else
#define ACTIVE_NoteSender
#define ACTIVE_OurSender active
#endif
#if RCV == NOTE
#define ACTIVE_NoteReceiver active
#define ACTIVE_OurReceiver
#else
#define ACTIVE_NoteReceiver
#define ACTIVE_OurReceiver active
#endif

#include "env.pml"
#include "note_peers.pml"
#if SND == OURS || RCV == OURS
#include "our_peers.pml"
#endif
