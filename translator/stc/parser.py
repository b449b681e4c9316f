"""LALR parser: ST text -> syntax tree, with error recovery so every syntax error is reported.

The grammar is st.lark; the callbacks that build the tree are in tree_builder.py, the
messages and the error recovery in parse_errors.py."""
import os
import re

from lark import Lark
from lark.exceptions import UnexpectedInput

from .parse_errors import _Recovery, _unexpected_message
from .tree_builder import _Build, _depth_sink, _pos
# parser's names from before the split (cli.py speaks of parser.MAX_DEPTH)
from .tree_builder import MAX_DEPTH, int_value, parse_time  # noqa: F401

_GRAMMAR = os.path.join(os.path.dirname(__file__), "st.lark")

KEYWORDS = None  # filled from the grammar at load time


_parser = None
_comment_sink = [None, None]
_last = [None, None]     # [previous token, current token] seen by the lexer


def _track(tok):
    _last[0] = _last[1]
    _last[1] = tok
    return tok


def _on_pragma(tok):
    if _comment_sink[1] is not None:
        _comment_sink[1](tok)
    return tok


def _on_slash_comment(tok):
    if _comment_sink[0] is not None:
        _comment_sink[0](tok)
    return tok


def _cache_path():
    """Where lark keeps the analysed grammar (3x faster start); in the user's own cache
    directory, never a shared /tmp (the cache is a pickle)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    d = os.path.join(base, "stc")
    try:
        os.makedirs(d, mode=0o700, exist_ok=True)
    except OSError:
        return False
    if not os.access(d, os.W_OK):
        return False
    return os.path.join(d, "st-grammar.lark-cache")


def _get_parser():
    global _parser, KEYWORDS
    if _parser is None:
        with open(_GRAMMAR) as f:
            text = f.read()
        names = re.findall(r"^([A-Z][A-Z0-9_]*)(?:\.\d+)?\s*:", text, re.M)
        callbacks = {name: _track for name in names}
        callbacks["SLASH_COMMENT"] = _on_slash_comment
        callbacks["PRAGMA"] = _on_pragma
        for name in ("WS", "COMMENT"):
            callbacks.pop(name, None)
        _parser = Lark(text, parser="lalr", lexer="basic", transformer=_Build(),
                       maybe_placeholders=True, cache=_cache_path(), lexer_callbacks=callbacks)
        KEYWORDS = {t.name for t in _parser.terminals
                    if t.pattern.type == "str" and t.pattern.value.isalpha() or
                    (t.pattern.type == "str" and "_" in t.pattern.value)}
    return _parser


def parse(text, filename, diags, dialect="st"):
    """Parse one file; syntax errors go to diags. Returns a list of top-level nodes.
    dialect "scl": TIA Portal SCL, rewritten to ST in place first (scl_in.py); "twincat" /
    "codesys": the IDE's ST, rewritten the same way (vendor_in.py)."""
    p = _get_parser()
    errors = []

    def report(pos, code, msg):
        diags.error(filename, pos, msg, code)
        errors.append(msg)

    if dialect in ("scl", "twincat", "codesys"):
        if dialect == "scl":
            from .scl_in import to_st
        else:
            from .vendor_in import to_st
        text = to_st(text, report)
        if text is None or errors:
            return None

    rec = _Recovery(report)
    _comment_sink[0] = lambda tok: report(
        _pos(tok), "P0101", ("//" if tok.startswith("//") else "/* */")
        + " comments are not portable (matiec rejects them): use (* ... *)")
    _comment_sink[1] = lambda tok: report(
        _pos(tok), "P0102", "{ ... } pragmas are not portable (matiec pastes them into its C output): "
        "remove it or make it a (* comment *)")
    _depth_sink[0] = report
    text = _blank_comments(text, report, rec)
    if text is None:
        _depth_sink[0] = None
        return None
    for m in _PERSISTENT.finditer(text):
        at = m.start(1)
        line = text.count("\n", 0, at) + 1
        col = at - (text.rfind("\n", 0, at) + 1) + 1
        report((line, col), "P0103", "PERSISTENT is CODESYS/TwinCAT, not IEC 61131-3 (matiec rejects it): "
               "use RETAIN (kept on a warm start)")
    if errors:
        _depth_sink[0] = None
        return None
    try:
        tree = p.parse(text, on_error=rec)
    except UnexpectedInput as e:
        _depth_sink[0] = None
        if not errors:
            tok = getattr(e, "token", None)
            pos = (getattr(e, "line", 0) or 0, getattr(e, "column", 0) or 0)
            report(pos if pos[0] > 0 else (0, 0), "P0104", _unexpected_message(e) if tok is not None else "syntax error")
        return None
    _depth_sink[0] = None
    if errors:
        return None
    return tree


# PERSISTENT after a VAR keyword and its qualifiers (a CODESYS/TwinCAT qualifier)
_PERSISTENT = re.compile(r"\bVAR(?:_GLOBAL|_INPUT|_OUTPUT)?(?:\s+(?:CONSTANT|RETAIN|NON_RETAIN))*"
                         r"\s+(PERSISTENT)\b", re.I)


# what the comment pass looks at: comment and pragma openers, and string literals and //
# comments (skipped, so a '(*' inside them opens nothing)
_OPENERS = re.compile(r"\(\*|/\*|\{|'(?:[^'$\n]|\$[^\n])*'|\"(?:[^\"$\n]|\$[^\n])*\"|//[^\n]*")
_NOT_NL = re.compile(r"[^\n]+")


def _blank_comments(text, report, rec):
    """Replace every (* *) comment, /* */ comment and { } pragma by spaces (newlines kept, so
    token positions do not move), in time and memory linear in the text: the lexer then never
    has to match a comment. Reports nested, unclosed and non-portable ones."""
    if "(*" not in text and "/*" not in text and "{" not in text:
        return text
    out = []
    pos = 0
    line_at = [0, 1]          # offset, line number there (offsets only grow)
    next_close = [-1]         # cached text.find("*)", ...) for the nested-comment check

    def where(off):
        o, ln = line_at
        ln += text.count("\n", o, off)
        line_at[0], line_at[1] = off, ln
        return (ln, off - (text.rfind("\n", 0, off) + 1) + 1)

    scan = 0                  # where to look for the next opener (pos: copied up to here)
    while True:
        m = _OPENERS.search(text, scan)
        if m is None:
            break
        tok = m.group(0)
        start = m.start()
        scan = m.end()
        if tok[0] in "'\"" or tok.startswith("//"):
            continue
        close = {"(*": "*)", "/*": "*/", "{": "}"}[tok]
        end = text.find(close, start + len(tok))
        if end < 0:
            what = {"(*": "comment '(*'", "/*": "comment '/*'", "{": "pragma '{'"}[tok]
            report(where(start), "P0105", f"{what} is not closed: missing '{close}'")
            return None      # the rest of the file is inside it: nothing more to parse
        end += len(close)
        if tok == "(*":
            inner = text.find("(*", start + 2, end - 2)
            if inner >= 0:
                # nested only if a stray '*)' follows before the next comment opens
                if next_close[0] < end:
                    next_close[0] = text.find("*)", end)
                    if next_close[0] < 0:
                        next_close[0] = len(text) + 1
                opening = text.find("(*", end, next_close[0])
                if next_close[0] <= len(text) and opening < 0:
                    report(where(inner), "P0106", "nested comments are not portable (matiec rejects "
                           "them without -n): close the outer comment first")
                    rec.last_line = max(rec.last_line, where(end)[0])
        elif tok == "/*":
            report(where(start), "P0101", "/* */ comments are not portable (matiec rejects them): "
                   "use (* ... *)")
        else:
            report(where(start), "P0102", "{ ... } pragmas are not portable (matiec pastes them into its "
                   "C output): remove it or make it a (* comment *)")
        out.append(text[pos:start])
        out.append(_NOT_NL.sub(lambda x: " " * len(x.group(0)), text[start:end]))
        pos = scan = end
    out.append(text[pos:])
    return "".join(out)
