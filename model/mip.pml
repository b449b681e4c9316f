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

#include "env.pml"
#include "note_peers.pml"
#if SND == OURS || RCV == OURS
#include "our_peers.pml"
#endif

init {
    atomic {
#if SND == NOTE
        run NoteSender();
#else
        run OurSender();
#endif
#if RCV == NOTE
        run NoteReceiver()
#else
        run OurReceiver()
#endif
    }
}
