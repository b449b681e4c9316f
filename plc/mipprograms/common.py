"""What the example programs' generators and their tests share: the register layout of the
located image, the TIME helpers and the CONFIGURATION of one program."""

OPENPLC_STATIONS = 2      # devices in the committed plc/openplc/central-mbconfig.cfg
MAX_STATIONS = 4          # receivers in the central programs (devices 1..4)
READ_REGS = 125           # one FC3 at the read-status register: status, count, 123 data
WRITE_REGS = 123          # one FC16 at the first write register
WINDOW = 160              # PLC_RecordStore.aWindow


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


def config(prog, inst, task="tMain"):
    """The CONFIGURATION that runs PROGRAM `prog` as instance `inst`, every 10 ms in task `task`
    (the example programs' and the tests' one task)."""
    return (f"\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            f"    TASK {task}(INTERVAL := T#10ms, PRIORITY := 0);\n"
            f"    PROGRAM {inst} WITH {task} : {prog};\n  END_RESOURCE\nEND_CONFIGURATION\n")


