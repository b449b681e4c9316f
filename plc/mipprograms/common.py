"""What the programs still generated whole share: the register layout of their located image
and %MW blocks, the TIME helpers, and the ST fragments they are assembled from."""
from . import mipglue as glue

OPENPLC_STATIONS = 2      # devices in the committed plc/openplc/central-mbconfig.cfg
MAX_STATIONS = 4          # receivers in the central programs (devices 1..4)
READ_REGS = 125           # one FC3 at the read-status register: status, count, 123 data
WRITE_REGS = 123          # one FC16 at the first write register
WINDOW = 160              # PLC_RecordStore.aWindow


# the located image of the example programs: station s reads %IW100 + 125(s-1).. and writes
# %QW100 + 123(s-1).. into/from rd<s> and <fb>.aWrite, through r<s>_<i> / w<s>_<i>
GLUE = glue.Layout(read_base=100, read_count=READ_REGS, write_base=100, write_count=WRITE_REGS,
                   stations=MAX_STATIONS, read_array="rd{s}", write_array="rcv{s}.aWrite",
                   numbered=True)     # write_array: the central's; io_after() passes each block's
glue.check(GLUE, "plcrt")          # 4 stations of 125 pass OpenPLC's 400: station 4 idles there


def read_image(s):        # station s (1-based): %IW of its read block
    return GLUE.read_image(s)


def write_image(s):
    return GLUE.write_image(s)


def peer_base(s):         # %MW block of peer s: receiver 0..19, sender 20..39, window 40..199
    return 100 + 200 * (s - 1)


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


def located_io(s, tag):
    """Declarations of station s's located I/O (see the runtime configs)."""
    lines = [
        f"  (* modem {tag}: read block %IW{read_image(s)}.., write block %QW{write_image(s)}.. *)",
        f"  rdTrig{s} AT %QX{s}.0 : BOOL;",
        f"  rdDone{s} AT %IX{s}.0 : BOOL;",
        f"  rdErr{s} AT %IX{s}.1 : BOOL;",
        f"  rdSt{s} AT %IW{10 + s} : WORD;         (* the read's status: why it failed *)",
        f"  wrTrig{s} AT %QX{s}.1 : BOOL;",
        f"  wrDone{s} AT %IX{s}.2 : BOOL;",
        f"  wrErr{s} AT %IX{s}.3 : BOOL;",
        f"  wrLen{s} AT %QW{s} : WORD;",
    ]
    lines += glue.declarations(GLUE, s)
    lines += [f"  rd{s} : MIP_T_ReadBlock;", f"  xRdValid{s} : BOOL;", f"  xWrDone{s} : BOOL;",
              f"  tonWr{s} : TON;"]
    return lines


def io_before(s):
    """Read handshake and read block copy, before the MIP block is called."""
    lines = [f"(* station {s}: read handshake (trigger policy): a read every other scan; the block is"
             f" copied when it is valid (the MIP blocks look at aRead only with xReadValid) *)",
             f"xRdValid{s} := rdDone{s} OR xCyclic;",
             f"IF xRdValid{s} THEN"]
    lines += glue.read_copies(GLUE, s)
    lines += [
        "END_IF;",
        f"rdTrig{s} := xRun AND NOT (rdDone{s} OR rdErr{s});",
        f"tonWr{s}(IN := xCyclic AND wrTrig{s}, PT := tCyclicWrite);",
        f"xWrDone{s} := wrDone{s} OR tonWr{s}.Q;",
    ]
    return lines


def io_after(s, fb):
    lines = [f"(* station {s}: write handshake and block; the runtime takes the block at the"
             f" request's rising edge, OpenPLC's cyclic master whenever it polls *)",
             f"wrTrig{s} := {fb}.xWriteReq;",
             f"IF wrTrig{s} OR xCyclic THEN",
             f"  wrLen{s} := UINT_TO_WORD({fb}.uWriteLen);"]
    lines += glue.write_copies(GLUE, s, array=f"{fb}.aWrite")
    lines += ["END_IF;"]
    return lines


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


