"""RETAIN.c: the table of retained variables stc emits for the runtime (names, type tags, sizes,
addresses computed at run time), checked against the symbol table of the same program."""
import os
import subprocess

import stc_harness as H

SRC = os.path.join(H.HERE, "accept", "retain_sections.st")

MAIN = r"""
#include <stdio.h>
#include <stddef.h>
%(decls)s
extern const char *const plcrt_gen_retain_names[];
extern const char *const plcrt_gen_retain_types[];
extern const size_t plcrt_gen_n_retain;
void *plcrt_gen_retain_addr(size_t i);
size_t plcrt_gen_retain_size(size_t i);
void config_init__(void);
int main(void) {
  config_init__();
  for (size_t i = 0; i < plcrt_gen_n_retain; i++)
    printf("%%s\t%%s\t%%zu\t%%p\n", plcrt_gen_retain_names[i], plcrt_gen_retain_types[i],
           plcrt_gen_retain_size(i), plcrt_gen_retain_addr(i));
%(syms)s
  return 0;
}
"""


def _table(tmp_path):
    out = tmp_path / "gen"
    r = H.run_stc(["-o", str(out), SRC])
    assert r.returncode == 0, r.stderr
    decls, rows = [], []
    for line in (out / "SYMBOLS.tsv").read_text().splitlines():
        if line.startswith("#decl"):
            decls.append(line.split("\t", 1)[1])
        elif line and not line.startswith(("#", "path\t")):
            rows.append(line.split("\t"))
    syms = "\n".join(f'  printf("SYM\\t%s\\t%%p\\n", (void *)&({ref}));' % path
                     for path, _, _, ref in rows)
    (out / "t.c").write_text(MAIN % {"decls": '#include "POUS.h"\n' + "\n".join(decls),
                                     "syms": syms})
    srcs = [str(out / s.strip()) for s in (out / "SOURCES.txt").read_text().splitlines()
            if s.strip()]
    assert any(s.endswith("RETAIN.c") for s in srcs)
    exe = tmp_path / "t"
    p = subprocess.run(["cc", *H.CFLAGS, "-I", str(out), "-o", str(exe), *srcs, str(out / "t.c"),
                        "-lm"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    table, addr = [], {}
    for line in lines.splitlines():
        cols = line.split("\t")
        if cols[0] == "SYM":
            addr[cols[1].upper()] = cols[2]
        else:
            table.append(cols)
    return table, addr


def test_retain_table_lists_retained_variables_and_whole_retained_instances(tmp_path):
    table, addr = _table(tmp_path)
    got = [(n, t, int(s)) for n, t, s, _ in table]
    assert got == [
        ("CONFIG0.G", "DINT", 4),
        ("CONFIG0.RES0.MAIN0.CNT", "DINT", 4),
        # an instance in a RETAIN section: all of it, its non-RETAIN variables included
        ("CONFIG0.RES0.MAIN0.KEEP.INC", "INT", 2),
        ("CONFIG0.RES0.MAIN0.KEEP.TOTAL", "INT", 2),
        ("CONFIG0.RES0.MAIN0.KEEP.SPARE", "INT", 2),
        ("CONFIG0.RES0.MAIN0.KEEP.SUM", "INT", 2),
        # an instance in a plain section: only what its type declares RETAIN
        ("CONFIG0.RES0.MAIN0.PLAIN.INC", "INT", 2),
        ("CONFIG0.RES0.MAIN0.PLAIN.TOTAL", "INT", 2),
    ]
    for name, _, _, a in table:
        assert addr[name] == a, f"{name}: retain table {a}, symbol table {addr[name]}"


def test_program_without_retain_has_an_empty_table(tmp_path):
    out = tmp_path / "gen"
    r = H.run_stc(["-o", str(out), os.path.join(H.HERE, "accept", "basic_counter.st")])
    assert r.returncode == 0, r.stderr
    text = (out / "RETAIN.c").read_text()
    assert "plcrt_gen_n_retain = 0;" in text
