"""Command-line front of the translator (placeholder until the translator lands)."""
import sys


def main(argv=None):
    print("stc: error: the translator is not built yet", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
