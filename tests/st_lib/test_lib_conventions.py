"""Every public block of st_lib/ read as an integrator's IDE shows it (its declared interface,
read with the docs' ST reader mipdocs.stdecl, and its SCL export by stc.scl_out), checked
against the house convention st_lib/CONVENTIONS.md, rule by rule (the rule names below are the
section names there).

Today's deviations are listed in ONE table, DEVIATIONS (the migration list of issue 46 step 2).
The check is a ratchet both ways: a deviation not in the table fails (a new block or a new
input that breaks the convention), and so does an entry of the table that no longer deviates
(the fix landed: delete its line, and its row in CONVENTIONS.md's table).
"""
import re
from pathlib import Path

import pytest
from mipcosim.programs import CHAIN_FILES, LIB_FILES
from mipdocs import stdecl
from mipdocs.blockref import LIVE, header_rows

REPO = Path(__file__).resolve().parents[2]
LIB = REPO / "st_lib"

# -- the two libraries (CONVENTIONS.md, "Two libraries") ----------------------------------
# a file belongs to the library of its folder: st_lib/core/ or st_lib/chain/ (LIB_FILES are
# paths relative to st_lib/, each library's in its import order)
LIBRARIES = {
    # library: (its one error enum, its one wait-reason enum, the high byte of its S7 status
    #           word on an error: 16#8000 + base + the error's position in its enum)
    "core": ("E_MIP_Error", "E_MIP_WaitReason", 0x8000),
    "chain": ("E_MIP_ChainError", "E_MIP_ChainWaitReason", 0x8100),
}
# the chain library's names (CONVENTIONS.md, "library-prefix"): MIP_ + Soe / Unicos / Chain
# after the kind's prefix (E_, T_, Internal_); the core has no name of that form
CHAIN_NAME = re.compile(r"^(E_)?MIP_(T_|Internal_)?(Soe|Unicos|Chain)[A-Z]\w*$")
INTERNAL_PREFIX = "MIP_Internal_"
INTERNAL_MARK = "Internal:"          # the first word of a helper's @purpose
IFACE = ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT")

# naming: the type prefix of an interface variable (CONVENTIONS.md, "Names")
ELEMENTARY_PREFIX = {"BOOL": "x", "BYTE": "by", "WORD": "w", "DWORD": "dw", "SINT": "si",
                     "INT": "i", "DINT": "di", "USINT": "usi", "UINT": "u", "UDINT": "udi",
                     "REAL": "r", "LREAL": "lr", "TIME": "t", "STRING": "s"}

# the sides of a block with both xEnable and xExecute (CONVENTIONS.md, "Block types")
COMBINED_SIDES = {"execute": "Send", "enable": "Recv"}

FIX = "issue 46 step 2"
# (block or type, rule, detail, why it deviates today, fixed by)
DEVIATIONS = [
]


# -- reading the library -------------------------------------------------------------------

def library_of(fname):
    return "chain" if fname in CHAIN_FILES else "core"


@pytest.fixture(scope="module")
def units():
    return [(f, stdecl.parse_file(str(LIB / f))) for f in LIB_FILES]


@pytest.fixture(scope="module")
def scl():
    """{block name: its SCL text} as the release's SCL sources have it (stc.scl_out; the
    version only changes the VERSION line, so a fixed one saves a second parse)."""
    from stc import scl_out
    out = scl_out.generate_files([str(LIB / f) for f in LIB_FILES], "1.0.0")
    return {Path(p).stem: text for p, text in out.items()}


def is_internal(pou):
    if not pou.doc:
        return False
    purpose = " ".join(stdecl.parse_doc(pou.doc)["sections"].get("purpose", [])).strip()
    return purpose.startswith(INTERNAL_MARK)


def public_pous(units):
    return [(f, p) for f, u in units for p in u.pous if not is_internal(p)]


def iface(pou, kinds=IFACE):
    return [(s.kind, v) for s in pou.sections if s.kind in kinds for v in s.vars]


def block_type(pou):
    """execute | enable | combined | decoder (an FB without xExecute or xEnable) | function."""
    if pou.kind != "FUNCTION_BLOCK":
        return "function"
    ins = {v.name for _, v in iface(pou, ("VAR_INPUT",))}
    if {"xExecute", "xEnable"} <= ins:
        return "combined"
    return "execute" if "xExecute" in ins else "enable" if "xEnable" in ins else "decoder"


def sides(pou):
    """[(model, infix)] of the block: one side, or the two sides of a combined block."""
    t = block_type(pou)
    if t == "combined":
        return [(m, COMBINED_SIDES[m]) for m in ("execute", "enable")]
    return [(t, "")] if t in ("execute", "enable") else []


# -- the rules: each returns [(block, rule, detail)] -----------------------------------------

def check_internal(units):
    out = []
    for _f, u in units:
        for p in u.pous:
            if not p.doc:
                out.append((p.name, "internal-name", "no (*@ block header: neither public nor internal"))
            elif is_internal(p) != p.name.startswith(INTERNAL_PREFIX):
                out.append((p.name, "internal-name",
                            f"no prefix {INTERNAL_PREFIX}" if is_internal(p)
                            else f"prefix {INTERNAL_PREFIX} without '{INTERNAL_MARK}' in @purpose"))
    return out


def check_library_prefix(units):
    out = []
    for f, u in units:
        lib = library_of(f)
        for name in [p.name for p in u.pous] + [t.name for t in u.types]:
            if (lib == "chain") != bool(CHAIN_NAME.match(name)):
                out.append((name, "library-prefix", f"{lib} library, name of the "
                            f"{'core' if lib == 'chain' else 'chain'} form"))
    return out


def check_comments(units):
    return [(p.name, "comment", f"{v.name} has no comment")
            for _f, p in public_pous(units) for _k, v in iface(p) if not (v.comment or "").strip()]


def _want_prefix(spec, types):
    if spec.kind == "array":
        return "a"
    if spec.kind == "string":
        return "s"
    name = spec.name.upper()
    if name in ELEMENTARY_PREFIX:
        return ELEMENTARY_PREFIX[name]
    t = types.get(spec.name)
    if t is None:
        return None                                     # a block: not on an interface
    if t.kind == "enum":
        return "e"
    if t.kind == "array":
        return "a"
    if t.kind == "struct":
        return "st"
    return _want_prefix(t.spec, types) if t.spec else None


def check_naming(units):
    types = {t.name: t for _f, u in units for t in u.types}
    out = []
    for _f, p in public_pous(units):
        for _k, v in iface(p):
            want = _want_prefix(v.type, types)
            if want is None:
                out.append((p.name, "naming", f"{v.name} : {v.type.text()} (no block on an interface)"))
            elif not re.fullmatch(re.escape(want) + r"[A-Z0-9]\w*", v.name):
                out.append((p.name, "naming", f"{v.name} : {v.type.text()} (want the prefix {want})"))
    return out


def check_models(units):
    out = []
    for f, p in public_pous(units):
        t = block_type(p)
        ins = {v.name for _, v in iface(p, ("VAR_INPUT",))}
        outs = {v.name: v.type.text() for _, v in iface(p, ("VAR_OUTPUT",))}
        errenum = LIBRARIES[library_of(f)][0]
        if t == "decoder":
            if "xValid" not in outs:
                out.append((p.name, "decoder-outputs", "missing xValid"))
            for bad in ("xBusy", "xDone", "xAborted"):
                if bad in outs:
                    out.append((p.name, "decoder-outputs", f"has {bad}"))
            if "xError" in outs and "eErrorId" not in outs:
                out.append((p.name, "decoder-outputs", "xError without eErrorId"))
        for model, i in sides(p):
            rule = f"{model}-outputs"
            need = [f"x{i}Busy", f"x{i}Error", f"e{i}ErrorId"]
            need.insert(0, f"x{i}Done" if model == "execute" else f"x{i}Valid")
            if model == "execute" and "xAbort" in ins:
                need.append(f"x{i}Aborted")
            forbid = [f"x{i}Valid"] if model == "execute" else [f"x{i}Done", f"x{i}Aborted"]
            if model == "execute" and "xAbort" not in ins:
                forbid.append(f"x{i}Aborted")
            out += [(p.name, rule, f"missing {n}") for n in need if n not in outs]
            out += [(p.name, rule, f"has {n}") for n in forbid if n in outs]
        for name, ty in outs.items():
            if re.fullmatch(r"e\w*ErrorId", name) and ty != errenum:
                out.append((p.name, "error-enum", f"{name} : {ty}"))
    return out


def check_enums(units):
    """One error enum and one wait-reason enum per library; the error enum's position 0 is
    'no error' and its values fit the library's range (positions 0..255)."""
    out = []
    for lib, (errenum, waitenum, _base) in LIBRARIES.items():
        enums = {t.name: t for f, u in units if library_of(f) == lib for t in u.types
                 if t.kind == "enum"}
        for rule, want, pattern in (("one-error-enum", errenum, r"E_MIP_\w*Error"),
                                    ("one-wait-enum", waitenum, r"E_MIP_\w*Wait\w*")):
            if want not in enums:
                out.append((want, rule, "missing"))
            out += [(n, rule, f"a second {rule.split('-')[1]} enum in {lib}")
                    for n in enums if n != want and re.fullmatch(pattern, n)]
        if errenum in enums:
            values = [v for v, _c in enums[errenum].values]
            if not values[0].endswith("_NONE"):
                out.append((errenum, "error-range", f"position 0 is {values[0]}, not ..._NONE"))
            if len(values) > 256:
                out.append((errenum, "error-range", f"{len(values)} values: the range has 256"))
    return out


def check_diagnostics(units):
    out = []
    for f, p in public_pous(units):
        waitenum = LIBRARIES[library_of(f)][1]
        outs = {v.name: v.type.text() for _, v in iface(p, ("VAR_OUTPUT",))}
        infixes = [i for _m, i in sides(p)]
        for i in infixes:
            for name, ok in ((f"e{i}State", lambda ty: ty.startswith("E_MIP_") and ty.endswith("State")),
                             (f"e{i}WaitReason", lambda ty: ty == waitenum)):
                if name not in outs:
                    out.append((p.name, "diagnostics", f"missing {name}"))
                elif not ok(outs[name]):
                    out.append((p.name, "diagnostics", f"{name} : {outs[name]}"))
    return out


# the inputs a block reads live (CONVENTIONS.md, "Sampled inputs"): the defining inputs, the
# data and handshakes of the caller and the operator's commands; every other input of an
# execute-type or enable-type block is a parameter, read at the rising edge of xExecute/xEnable
LIVE_INPUT = re.compile(r"""
    x(Enable|Execute|Abort)                        # the defining inputs, the abort
  | a[A-Z]\w* | u\w*Len                             # data handed in, its length
  | x\w*(Valid|Done|Error|Last)[AB]? | w\w*Status[AB]?   # the caller's handshakes
  | stReply[AB]                                    # ... of a channel, as one structure
  | xRecordProcessed | xEntryStored | xPut | wCtrl\w+ | wSnapshots
  | xLoggerFull | xResetList | xActiveB             # the operator's commands
""", re.X)


def check_sampled(units):
    """The interface table says, for every input, when it is read (blockref's 'sampled'
    column, checked against the code by the docs check); a parameter is sampled at the edge."""
    out = []
    for _f, p in public_pous(units):
        if not sides(p):
            continue
        rows = header_rows(p)
        if rows is None:
            out.append((p.name, "sampled", "the interface table has no 'sampled' column"))
            continue
        col = {n: s for n, d, s in rows if d in ("in", "in_out")}
        for _k, v in iface(p, ("VAR_INPUT", "VAR_IN_OUT")):
            s = col.get(v.name, "")
            if not s:
                out.append((p.name, "sampled", f"{v.name}: no entry in the 'sampled' column"))
            elif s == LIVE and not LIVE_INPUT.fullmatch(v.name):
                out.append((p.name, "sampled", f"{v.name} is live"))
    return out


def check_channels(units):
    """No channel repeated field by field (xWriteDoneA, xWriteDoneB, ...): one block per
    channel, or the channel's fields as one structure (stReplyA, stReplyB of one STRUCT type
    are the channel's structure, not a repeated field)."""
    structs = {t.name for _f, u in units for t in u.types if t.kind == "struct"}
    out = []
    for _f, p in public_pous(units):
        names = {v.name: v.type.name for _k, v in iface(p)}
        pairs = sorted(n[:-1] for n, ty in names.items() if n.endswith("A") and n[:-1] + "B" in names
                       and not (ty in structs and names[n[:-1] + "B"] == ty))
        if pairs:
            out.append((p.name, "channels", f"{len(pairs)} fields repeated per channel A/B"))
    return out


def check_status_word(units, scl):
    """In the SCL export every execute/enable side has an LGF status word, and an error maps to
    16#8000 + the library's base + the error's position."""
    out = []
    for f, p in public_pous(units):
        base = LIBRARIES[library_of(f)][2]
        text = scl.get(p.name, "")
        sd = sides(p)
        want = ["status"] if len(sd) == 1 else [f"{i[0].lower()}{i[1:]}Status" for _m, i in sd]
        declared = set(re.findall(r"^\s*(\w*[sS]tatus) : Word\b", text, flags=re.M))
        for name in want:
            if name not in declared:
                out.append((p.name, "status-word", f"no {name} in the SCL export"))
                continue
            for hexbase in re.findall(rf"#{name} := WORD#16#([0-9A-F]+) OR INT_TO_WORD", text):
                if int(hexbase, 16) != base:
                    out.append((p.name, "status-word",
                                f"errors map to 16#{int(hexbase, 16):04X}, not 16#{base:04X}"))
    return out


# -- the tests -------------------------------------------------------------------------------

def test_the_library_is_read(units):
    """The reader found what the convention is about (a broken read would pass every rule)."""
    pous = {p.name: block_type(p) for _f, p in public_pous(units)}
    assert pous.get("MIP_Sender") == "execute" and pous.get("MIP_Receiver") == "enable"
    assert pous.get("MIP_Link") == "combined" and pous.get("MIP_Status") == "decoder"
    assert sum(1 for _f, u in units for p in u.pous if is_internal(p)) >= 5
    assert sum(len(iface(p)) for _f, p in public_pous(units)) > 200


def test_deviation_table_is_well_formed():
    keys = [d[:3] for d in DEVIATIONS]
    assert len(keys) == len(set(keys)), "a deviation is listed twice"
    assert all(len(d) == 5 and all(d) for d in DEVIATIONS)
    rules = {d[1] for d in DEVIATIONS}
    text = (LIB / "CONVENTIONS.md").read_text()
    assert all(f"`{r}`" in text for r in rules), "every rule has its section in CONVENTIONS.md"


def test_the_convention_lists_every_deviation():
    """CONVENTIONS.md's migration table has a row for each deviation block and rule."""
    text = (LIB / "CONVENTIONS.md").read_text()
    rows = set(re.findall(r"^\| `(\w+)` \| `([\w-]+)` \|", text, flags=re.M))
    listed = {(b, r) for b, r, *_ in DEVIATIONS}
    assert listed - rows == set(), "rows missing in CONVENTIONS.md's migration table"
    assert rows - listed == set(), "rows in CONVENTIONS.md's migration table not in DEVIATIONS"


def test_the_convention_counts_each_blocks_deviations(units):
    """CONVENTIONS.md's table of where each public block stands: its library, type and number
    of deviations are what the library and DEVIATIONS say."""
    text = (LIB / "CONVENTIONS.md").read_text()
    rows = {b: (lib, t, int(n)) for b, lib, t, n in re.findall(
        r"^\| (MIP_\w+) \| (core|chain) \| ([\w-]+) \| (\d+)\b", text, flags=re.M)}
    types = {"execute": "execute-type", "enable": "enable-type"}
    want = {p.name: (library_of(f), types.get(block_type(p), block_type(p)),
                     sum(1 for d in DEVIATIONS if d[0] == p.name))
            for f, p in public_pous(units)}
    assert rows == want


@pytest.mark.parametrize("rule", ["internal-name", "library-prefix", "comment", "naming", "models", "enums",
                                  "diagnostics", "sampled", "channels", "status-word"])
def test_rule(rule, units, scl):
    check = {"internal-name": check_internal, "library-prefix": check_library_prefix,
             "comment": check_comments, "naming": check_naming,
             "models": check_models, "enums": check_enums, "diagnostics": check_diagnostics,
             "sampled": check_sampled, "channels": check_channels}.get(rule)
    found = set(check(units) if check else check_status_word(units, scl))
    assert {r for _b, r, _d in found} <= _rules_of(rule)
    listed = {d[:3] for d in DEVIATIONS if d[1] in _rules_of(rule)}
    new = sorted(found - listed)
    fixed = sorted(listed - found)
    msg = []
    if new:
        msg.append("new deviations from st_lib/CONVENTIONS.md (follow the convention; a "
                   "deviation is listed only with the step that fixes it):\n"
                   + "\n".join(f"  {b}: {r}: {d}" for b, r, d in new))
    if fixed:
        msg.append("listed in DEVIATIONS but no longer deviating (delete the line here and its "
                   "row in CONVENTIONS.md):\n" + "\n".join(f"  {b}: {r}: {d}" for b, r, d in fixed))
    assert not msg, "\n".join(msg)


def _rules_of(check):
    """The rule names a check reports (so that a fixed entry is found even when the check
    reports nothing of that rule any more)."""
    return {"internal-name": {"internal-name"}, "library-prefix": {"library-prefix"},
            "comment": {"comment"}, "naming": {"naming"},
            "models": {"execute-outputs", "enable-outputs", "decoder-outputs", "error-enum"},
            "enums": {"one-error-enum", "one-wait-enum", "error-range"},
            "diagnostics": {"diagnostics"}, "sampled": {"sampled"}, "channels": {"channels"},
            "status-word": {"status-word"}}[check]
