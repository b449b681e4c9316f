"""mipdocs: the docs' generators and readers (docs/tools/, installed by `make venv`).

stdecl reads the ST declarations and doc headers of st_lib; blockref writes docs/blocks.md;
plcopen_export the PLCopen XML; chainsim runs the docs' chain (st_lib in two soft PLCs, the
emulator core, virtual time); gen_traces, mipsim, chainseq and gen_lossdata run it; seqdiag and
mkdiagrams draw the sequence diagrams, lossplot the throughput plot. Each generator runs as
`python -m mipdocs.NAME` or as `python docs/tools/NAME.py`."""
