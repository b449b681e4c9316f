"""`make run`, plc/demo.py, `python -m mipdemo`: the logger's demo, or with --chain the
chain's (relay -> PLCs -> radio -> SCADA; `--chain --help` lists its options)."""
import sys


def main(argv=None):
    args = sys.argv[1:] if argv is None else list(argv)
    if "--chain" in args:
        from .chain import main as chain_main
        return chain_main(args)
    from .logger import main as logger_main
    return logger_main(args)
