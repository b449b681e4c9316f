"""mipinterop: the interop matrix of our blocks against the note-only peer (matrix.py) and the
table it writes into docs/protocol.md (docs.py). `python -m mipinterop --help`."""
