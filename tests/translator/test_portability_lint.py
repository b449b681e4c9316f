"""Portability lint of our own ST (issue 26).

1. No construct on the divergence list (where upstream matiec, OpenPLC's matiec fork and IEC
   61131-3 can give other values: stc's portability warnings and the sites stc --divergences
   lists) in st_lib/ or plc/ without a reason: each site must match an entry of ALLOWED below,
   which says why its value is the same under every compiler.
2. No body comment of an st_lib POU names another st_lib POU that the POU does not already
   depend on: Beremiz orders the POUs of a PLCopen project by the names their bodies mention,
   comments included, and a comment naming a POU that depends on this one puts them in an
   order plain iec2c rejects.
"""
import glob
import os
import re

import pytest
from stc.compiler import compile_files
from stc.diag import Diagnostics

import stc_harness as H
from mipprograms.image import program_files   # a program's files: its logic, its image

STLIB = sorted(glob.glob(os.path.join(H.ROOT, "st_lib", "*", "*.st")))
PLC_DIR = os.path.join(H.ROOT, "plc")
PROGRAMS = sorted(p for p in glob.glob(os.path.join(PLC_DIR, "*.st"))
                  if not os.path.basename(p).startswith("PLC_"))   # PLC_*.st: the programs' helpers

# (file pattern, kind, text the source line contains, reason)
ALLOWED = [
    ("st_lib/core/MIP_Internal_WriteChannel.st", "timer-pt", "tonReq(",
     "runs only when tTimeout > T#0s (the IN condition), so PT is never T#0s"),
    ("st_lib/core/MIP_Receiver.st", "time-sum", "PT := tCfgTimeout + tCfgTimeout + tCfgTimeout",
     "three equal terms: the nanosecond part of the sum is never exactly 1e9 (n + n + n = 1e9 "
     "has no integer n, and an unnormalised n + n = 1e9 is normalised by the third addition)"),
    ("st_lib/core/MIP_Sender.st", "time-sum", "PT := tCfgTimeout + tCfgTimeout + tCfgTimeout",
     "three equal terms: as in MIP_Receiver, the sum is always normalised"),
    ("plc/*.st", "time-sum", "T#1s * (WORD_TO_DINT(",
     "whole seconds plus at most 999 ms: the nanosecond part stays below 1e9"),
    ("st_lib/core/MIP_Receiver.st", "timer-pt", "tonStep(",
     "PT is 3 * tTimeout (default T#10s): a step bound, never T#0s in a working set-up; at "
     "T#0s matiec's Q would come one scan later, a timing difference only"),
    ("st_lib/core/MIP_Receiver.st", "timer-pt", "tonTransfer(",
     "runs only when tTransferTimeout > T#0s (the IN condition), so PT is never T#0s"),
    ("st_lib/core/MIP_Receiver.st", "timer-pt", "tonPoll(",
     "PT is tTimeout, the polling interval (default T#10s); T#0s would poll one scan later "
     "under matiec, a timing difference only"),
    ("st_lib/core/MIP_Receiver.st", "timer-pt", "tonHold(",
     "PT is tTimeout / 2, a hold-off; at T#0s matiec releases it one scan later (timing only)"),
    ("st_lib/core/MIP_Sender.st", "timer-pt", "tonStep(",
     "PT is 3 * tTimeout, a step bound (timing only)"),
    ("st_lib/core/MIP_Sender.st", "timer-pt", "tonRetry(",
     "PT is tTimeout, the retransmission interval (default T#10s); at T#0s matiec retransmits "
     "one scan later, a timing difference only"),
    ("st_lib/core/MIP_Status.st", "timer-pt", "tonStall(",
     "PT is tStallTime (default T#60s): xLinkStalled may rise one scan later under matiec when "
     "it is T#0s, a timing difference only"),
    ("st_lib/chain/MIP_SoeReader.st", "timer-pt", "tonRetry(",
     "PT is tAckRetry (default T#1s), a delay before the next read; at T#0s matiec ends it one "
     "scan later, a timing difference only"),
    ("st_lib/chain/MIP_SoeReader.st", "timer-pt", "tonProblem(",
     "PT is tRetryTimeout or tAckTimeout, a bound before xError (timing only)"),
    ("st_lib/chain/MIP_SoeReader.st", "timer-pt", "tonWriteFail(",
     "PT is tAckTimeout, a bound before xError (timing only)"),
    ("st_lib/chain/MIP_SoeReader.st", "timer-pt", "tonNoRead(",
     "runs only when tReadTimeout > T#0s (the IN condition), so PT is never T#0s"),
    ("plc/PLC_Logger.st", "timer-pt", "tonLog(",
     "called only when tLogPeriod <> T#0s (the IF around it)"),
    ("plc/*.st", "timer-pt", "tonWr",
     "PT is the configured cyclic-write period; at T#0s matiec writes one scan later, a "
     "timing difference only"),
    ("st_lib/chain/MIP_SoeServer.st", "timer-pt", "tonSilent(",
     "runs only when tAckTimeout > T#0s (the IN condition), so PT is never T#0s"),
    ("st_lib/chain/MIP_Internal_UnicosChannel.st", "timer-pt", "tonRetry(",
     "PT is tRetry (default T#500ms), the pause before a repeated write; at T#0s matiec "
     "repeats one scan later, a timing difference only"),
    ("st_lib/chain/MIP_UnicosEvents.st", "timer-pt", "tonDelay(",
     "PT is tMaxDelay (default T#2s), the latest time to send the event table; at T#0s matiec "
     "sends it one scan later, a timing difference only"),
    ("st_lib/chain/MIP_UnicosStatus.st", "timer-pt", "tonGap(",
     "PT is tMinPeriod (default T#50ms), the least time between two status tables; at T#0s "
     "matiec allows the next one a scan later, a timing difference only"),
]


def _divergences():
    """Every divergence site of st_lib and plc/ (each program with the library), once."""
    sites = {}
    helpers = sorted(glob.glob(os.path.join(PLC_DIR, "PLC_*.st")))   # PLC_Logger.st first
    sets = [[(f, True) for f in STLIB]]
    for prog in PROGRAMS:
        sets.append([(f, True) for f in STLIB] + [(h, False) for h in helpers]
                    + [(str(f), False) for f in program_files(os.path.basename(prog)[:-3])])
    for files in sets:
        texts = []
        for f, lib in files:
            with open(f) as fh:
                texts.append((f, fh.read(), lib))
        d = Diagnostics()
        project = compile_files(texts, d, "matiec")
        assert not d, d.format()[:5]
        for f, pos, kind, text in project.divergences:
            sites.setdefault((os.path.relpath(f, H.ROOT), pos[0], pos[1], kind), text)
    return sites


def _allowed(rel, kind, line):
    for pat, k, snippet, reason in ALLOWED:
        if k == kind and re.fullmatch(pat.replace(".", r"\.").replace("*", "[^/]*"), rel) \
                and snippet in line:
            assert reason.strip()
            return True
    return False


@pytest.mark.skipif(not STLIB, reason="st_lib/ has no .st files")
def test_no_unexplained_divergence_in_our_st():
    lines = {}
    bad = []
    for (rel, line, col, kind), text in sorted(_divergences().items()):
        if rel not in lines:
            with open(os.path.join(H.ROOT, rel)) as f:
                lines[rel] = f.read().splitlines()
        src = lines[rel][line - 1].strip()
        if not _allowed(rel, kind, src):
            bad.append(f"{rel}:{line}:{col}: {kind}: {text} [{src[:80]}]")
    assert not bad, ("constructs on the divergence list without a reason (change the code or add "
                     "an ALLOWED entry that says why every compiler gives the same value):\n"
                     + "\n".join(bad))


def test_lint_finds_a_divergence(tmp_path):
    """The lint sees the constructs it is about (so the test above cannot pass vacuously)."""
    src = tmp_path / "x.st"
    src.write_text("PROGRAM Main\nVAR a : REAL; t : TIME; s : STRING; f : F_TRIG; x : BOOL; "
                   "k : INT; ton1 : TON; END_VAR\n"
                   "x := a > 0.3;\nt := t + T#1s;\nx := s = 'a';\nf(CLK := x);\n"
                   "k := FIND(s, 'a');\nton1(IN := x, PT := t);\nx := ton1.ENO;\n"
                   "FOR k := 1 TO 32767 DO x := TRUE; END_FOR;\n"
                   "FOR k := 1 TO k DO x := TRUE; END_FOR;\nEND_PROGRAM\n")
    d = Diagnostics()
    project = compile_files([(str(src), src.read_text(), False)], d, "matiec")
    assert not d, d.format()
    kinds = {(pos[0], kind) for _, pos, kind, _ in project.divergences}
    assert {(3, "real-literal"), (4, "time-sum"), (5, "string-compare"), (6, "warned"),
            (7, "string-function"), (8, "timer-pt"), (9, "en-eno"), (10, "for-wrap"),
            (11, "for-once")} <= kinds


# ---- body comments naming another POU

_POU = re.compile(r"^[ \t]*(FUNCTION_BLOCK|FUNCTION|PROGRAM)[ \t]+(\w+)(.*?)^[ \t]*END_\1\b",
                  re.M | re.S)


def _pous():
    out = {}
    for f in STLIB:
        with open(f) as fh:
            text = fh.read()
        for m in _POU.finditer(text):
            out[m.group(2).upper()] = (f, text, m)
    return out


def body_comment_findings(pous):
    """[(file, line, pou, named)] for body comments naming a POU the POU does not depend on."""
    findings = []
    names = list(pous)
    for name, (f, text, m) in pous.items():
        decl_end = [x.end() for x in re.finditer(r"\bEND_VAR\b", m.group(3), re.I)]
        start = m.start(3) + (decl_end[-1] if decl_end else 0)
        code = re.sub(r"\(\*.*?\*\)", " ", m.group(3), flags=re.S)
        deps = {n for n in names if re.search(r"\b" + n + r"\b", code, re.I)}
        for c in re.finditer(r"\(\*.*?\*\)", text[start:m.end(3)], re.S):
            for other in names:
                if other == name or other in deps:
                    continue
                if re.search(r"\b" + other + r"\b", c.group(0), re.I):
                    line = text.count("\n", 0, start + c.start()) + 1
                    findings.append((os.path.relpath(f, H.ROOT), line, name, other))
    return findings


@pytest.mark.skipif(not STLIB, reason="st_lib/ has no .st files")
def test_no_body_comment_names_another_pou():
    found = body_comment_findings(_pous())
    assert not found, "\n".join(
        f"{f}:{line}: a body comment of {pou} names {other}, which {pou} does not use: Beremiz "
        f"then orders {other} before {pou} in a PLCopen export, and plain iec2c rejects the "
        "result; reword the comment" for f, line, pou, other in found)


def test_body_comment_lint_sees_a_bad_comment(tmp_path):
    text = ("FUNCTION_BLOCK A\nVAR b : B; END_VAR\nb();\nEND_FUNCTION_BLOCK\n"
            "FUNCTION_BLOCK B\nVAR x : INT; END_VAR\n(* see A *)\nx := 1;\nEND_FUNCTION_BLOCK\n")
    f = tmp_path / "ab.st"
    f.write_text(text)
    pous = {m.group(2).upper(): (str(f), text, m) for m in _POU.finditer(text)}
    found = body_comment_findings(pous)
    assert [(line, pou, other) for _, line, pou, other in found] == [(7, "B", "A")]


def test_cli_lists_divergences(tmp_path):
    src = tmp_path / "d.st"
    src.write_text("PROGRAM Main\nVAR a : REAL; x : BOOL; s : STRING; END_VAR\nx := a > 0.3;\n"
                   "x := s <> 'a';\nEND_PROGRAM\n")
    r = H.run_stc(["--divergences", "-o", str(tmp_path / "out"), str(src)])
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert lines == [f"{src}:3:8: note: real-literal: '>' of a REAL with an untyped real literal: "
                     "matiec computes it in double (write REAL#...)",
                     f"{src}:4:8: note: string-compare: STRING comparison: OpenPLC's fork "
                     "compares the common length only"]
    r = H.run_stc(["-o", str(tmp_path / "out2"), str(src)])
    assert r.returncode == 0 and r.stderr == ""
