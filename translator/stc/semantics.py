"""The names of stc's run-time semantics, the one list (stc, plcharness, the kit and their
command lines take it from here): "matiec" reproduces upstream matiec's run-time values (the
default), "openplc" OpenPLC v3's matiec fork, "iec" IEC 61131-3 where the two differ.
Imports nothing, so that a caller need not load the translator to name them."""

SEMANTICS = ("matiec", "openplc", "iec")
