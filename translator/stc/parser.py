"""LALR parser: ST text -> syntax tree, with error recovery so every syntax error is reported."""
import os
import re

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken, UnexpectedEOF

from . import syntax as S

_GRAMMAR = os.path.join(os.path.dirname(__file__), "st.lark")


def _pos(tok):
    return (tok.line, tok.column)


def _first_pos(children):
    for c in children:
        if isinstance(c, Token):
            return (c.line, c.column)
        if isinstance(c, S.Node):
            return c.pos
    return (0, 0)


_TIME_PART = re.compile(r"([0-9][0-9_]*(?:\.[0-9_]+)?)(ms|us|ns|d|h|m|s)", re.I)
_TIME_UNIT = {"d": 86400 * 10**9, "h": 3600 * 10**9, "m": 60 * 10**9, "s": 10**9,
              "ms": 10**6, "us": 10**3, "ns": 1}


def parse_time(text):
    """Nanoseconds of a duration literal body like `1h2m3s4ms` (None when malformed)."""
    body = text.replace("_", "")
    neg = body.startswith("-")
    body = body.lstrip("+-")
    if not body:
        return None
    pos, total = 0, 0
    # a plain number means milliseconds? No: IEC requires a unit.
    while pos < len(body):
        m = _TIME_PART.match(body, pos)
        if not m:
            return None
        num, unit = m.group(1), m.group(2).lower()
        if "." in num:
            whole, frac = num.split(".")
            scale = _TIME_UNIT[unit]
            total += int(whole) * scale + (int(frac) * scale) // (10 ** len(frac))
        else:
            total += int(num) * _TIME_UNIT[unit]
        pos = m.end()
    return -total if neg else total


def int_value(text):
    """Value of an integer literal, None when malformed (e.g. 8#9); the checker reports it."""
    t = text.replace("_", "")
    try:
        if "#" in t:
            base, digits = t.split("#", 1)
            return int(digits, int(base))
        return int(t)
    except ValueError:
        return None


# Expressions and statements nested deeper than this get a located error: the checker and
# the C generator walk them recursively (in a thread with a large stack, see cli.py).
MAX_DEPTH = 1000
_depth_sink = [None]


def _depth(*xs):
    d = 0
    for x in xs:
        if isinstance(x, list):
            for y in x:
                d = max(d, _depth(y))
        elif isinstance(x, tuple):
            d = max(d, _depth(*x))
        elif isinstance(x, S.Node):
            d = max(d, x.__dict__.get("depth", 0))
    return d


def _nest(node, *children):
    return _nest_d(node, _depth(*children) + 1)


def _nest2(node, a, b):
    """_nest for two expression children (the common case, kept cheap)."""
    return _nest_d(node, max(a.__dict__.get("depth", 0), b.__dict__.get("depth", 0)) + 1)


def _nest1(node, a):
    return _nest_d(node, a.__dict__.get("depth", 0) + 1)


def _nest_d(node, d):
    node.depth = d
    if d == MAX_DEPTH + 1 and _depth_sink[0] is not None:
        _depth_sink[0](node.pos, f"nested too deeply (more than {MAX_DEPTH} levels of "
                       "expressions or statements): split it using intermediate variables")
    return node


class _Build(Transformer):
    """Parser callbacks (run inline by the LALR parser) building syntax.* nodes."""

    # ---- types
    def type_decl(self, c):
        return S.TypeDecl(_pos(c[0]), [d for d in c[1:-1]])

    def type_def(self, c):
        name, body = c[0], c[2]
        spec, init = body
        return S.TypeDef(_pos(name), str(name).upper(), spec, init)

    def simple_body(self, c):
        return (S.NamedType(_pos(c[0]), str(c[0]).upper()), c[2])

    def array_type_init(self, c):
        return (c[0], c[2])

    def struct_type(self, c):
        return (S.StructSpec(_pos(c[0]), c[1:-1]), None)

    def struct_member(self, c):
        return S.VarDecl(_pos(c[0]), [(str(c[0]).upper(), _pos(c[0]))], None, c[2], c[4])

    def enum_type(self, c):
        items = [x for x in c[1:] if isinstance(x, tuple)]
        default = c[-1]
        return (S.EnumSpec(_pos(c[0]), items, str(default).upper() if default is not None else None), None)

    def enum_item(self, c):
        return (str(c[0]).upper(), c[2], _pos(c[0]))

    def subrange_type(self, c):
        return (S.SubrangeRef(_pos(c[0]), str(c[0]).upper()), None)

    def string_type(self, c):
        return (S.StringRef(_pos(c[0]), str(c[0]).upper(), c[2]), None)

    def named_type(self, c):
        return S.NamedType(_pos(c[0]), str(c[0]).upper())

    def subrange_ref(self, c):
        return S.SubrangeRef(_pos(c[0]), str(c[0]).upper())

    def pointer_ref(self, c):
        return S.PointerRef(_pos(c[1]), str(c[0]).upper(), c[2])

    def string_ref(self, c):
        return S.StringRef(_pos(c[0]), str(c[0]).upper(), c[2])

    def inline_struct(self, c):
        return S.StructSpec(_pos(c[0]), c[1:-1])

    def inline_enum(self, c):
        return S.EnumSpec(_pos(c[0]), [x for x in c[1:] if isinstance(x, tuple)], None)

    def array_spec(self, c):
        dims = [x for x in c[2:-2] if isinstance(x, tuple)]
        return S.ArraySpec(_pos(c[0]), dims, c[-1])

    def subrange(self, c):
        return (c[0], c[2])

    def const_bound(self, c):
        return S.ConstBound(_pos(c[0]), str(c[0]).upper())

    def signed_int(self, c):
        if len(c) == 1:
            return int_value(c[0])
        v = int_value(c[1])
        return -v if c[0].type == "MINUS" and v is not None else v

    # ---- POUs
    def function(self, c):
        return S.Function(_pos(c[1]), str(c[1]).upper(), c[3], c[4:-2], c[-2], _pos(c[-1]))

    def function_block(self, c):
        return S.FunctionBlock(_pos(c[1]), str(c[1]).upper(), c[2:-2], c[-2], _pos(c[-1]))

    def program(self, c):
        return S.Program(_pos(c[1]), str(c[1]).upper(), c[2:-2], c[-2], _pos(c[-1]))

    def stray_var_block(self, c):
        return S.StrayVarBlock(c[0].pos, c[0])

    def var_block(self, c):
        kind = c[0]
        quals = [str(x).upper() for x in c[1:-1] if isinstance(x, str)]
        decls = [x for x in c[1:-1] if isinstance(x, S.VarDecl)]
        return S.VarBlock(kind[1], kind[0], quals, decls)

    def var_kind(self, c):
        return (str(c[0]).upper(), _pos(c[0]))

    def var_qual(self, c):
        return c[0]

    def var_decl(self, c):
        names = []
        i = 0
        while isinstance(c[i], Token) and c[i].type in ("IDENT", "COMMA"):
            if c[i].type == "IDENT":
                names.append((str(c[i]).upper(), _pos(c[i])))
            i += 1
        # c[i] is AT or None (optional), c[i+1] DIRECT or None
        at, direct = c[i], c[i + 1]
        loc = (str(direct).upper(), _pos(direct)) if direct is not None else None
        rest = c[i + 2:]
        # rest: COLON type_ref [ASSIGN init] SEMI
        return S.VarDecl(names[0][1], names, loc, rest[1], rest[3])

    def anon_located(self, c):
        loc = (str(c[1]).upper(), _pos(c[1]))
        return S.VarDecl(_pos(c[0]), [], loc, c[3], c[5])

    def array_init(self, c):
        return S.ArrayInit(_pos(c[0]), [x for x in c[1:-1] if isinstance(x, tuple)])

    def array_init_item(self, c):
        return (None, c[0])

    def repeat_init(self, c):
        n = int_value(c[0])
        return (n if n is not None else 0, c[2])

    def struct_init(self, c):
        return S.StructInit(_pos(c[0]), [x for x in c[1:-1] if isinstance(x, tuple)])

    def struct_init_item(self, c):
        return (str(c[0]).upper(), c[2], _pos(c[0]))

    # ---- configuration
    def configuration(self, c):
        blocks = [x for x in c if isinstance(x, S.VarBlock)]
        res = [x for x in c if isinstance(x, S.Resource)]
        tasks = [x for x in c if isinstance(x, S.TaskConf)]
        progs = [x for x in c if isinstance(x, S.ProgConf)]
        return S.Configuration(_pos(c[1]), str(c[1]).upper(), blocks, res, tasks, progs)

    def resource(self, c):
        blocks = [x for x in c if isinstance(x, S.VarBlock)]
        tasks = [x for x in c if isinstance(x, S.TaskConf)]
        progs = [x for x in c if isinstance(x, S.ProgConf)]
        return S.Resource(_pos(c[1]), str(c[1]).upper(), str(c[3]).upper(), blocks, tasks, progs)

    def task_conf(self, c):
        params = [x for x in c[3:] if isinstance(x, tuple)]
        return S.TaskConf(_pos(c[1]), str(c[1]).upper(), params)

    def task_param(self, c):
        return (str(c[0]).upper(), c[2], _pos(c[0]))

    def prog_conf(self, c):
        # PROGRAM [RETAIN] IDENT [WITH IDENT] COLON IDENT [LPAR [args] RPAR] SEMI
        name = c[2]
        task = c[4]
        typ = c[6]
        args = c[8] if len(c) > 8 else None
        return S.ProgConf(_pos(name), str(name).upper(), str(task).upper() if task is not None else None,
                          str(typ).upper(), args or [])

    # ---- statements
    def stmt_list(self, c):
        return list(c)

    def assign_stmt(self, c):
        return _nest2(S.Assign(c[0].pos, c[0], c[2]), c[0], c[2])

    def call_stmt(self, c):
        return _nest(S.CallStmt(_pos(c[0]), str(c[0]).upper(), c[2] or []), c[2] or [])

    def empty_stmt(self, c):
        return S.Empty(_pos(c[0]))

    def exit_stmt(self, c):
        return S.Exit(_pos(c[0]))

    def continue_stmt(self, c):
        return S.Continue(_pos(c[0]))

    def return_stmt(self, c):
        return S.Return(_pos(c[0]))

    def if_stmt(self, c):
        branches = [(c[1], c[3])]
        i = 4
        while isinstance(c[i], tuple):
            branches.append(c[i])
            i += 1
        orelse = c[i + 1]  # c[i] ELSE or None
        return _nest(S.If(_pos(c[0]), branches, orelse), branches, orelse)

    def elsif_part(self, c):
        return (c[1], c[3])

    def case_stmt(self, c):
        items = [x for x in c[3:] if isinstance(x, S.Node)]
        orelse = None
        for x in c[3:]:
            if isinstance(x, list):
                orelse = x
        return _nest(S.Case(_pos(c[0]), c[1], items, orelse), c[1], items, orelse)

    def case_else(self, c):
        return c[1]

    def case_labels(self, c):
        return S.CaseLabels(_first_pos(c), [x for x in c if not isinstance(x, Token)])

    def case_label(self, c):
        return (c[0], None)

    def case_range(self, c):
        return (c[0], c[2])

    def based_label(self, c):
        return S.IntLit(_pos(c[0]), int_value(c[0]), str(c[0]), True)

    def name_label(self, c):
        return S.Name(_pos(c[0]), str(c[0]).upper())

    def for_stmt(self, c):
        # FOR IDENT := expr TO expr [BY expr] DO stmts END_FOR ;
        return _nest(S.For(_pos(c[0]), S.Name(_pos(c[1]), str(c[1]).upper()), c[3], c[5], c[7], c[9]),
                     c[3], c[5], c[7], c[9])

    def while_stmt(self, c):
        return _nest(S.While(_pos(c[0]), c[1], c[3]), c[1], c[3])

    def repeat_stmt(self, c):
        return _nest(S.Repeat(_pos(c[0]), c[1], c[3]), c[1], c[3])

    def call_args(self, c):
        return [x for x in c if isinstance(x, S.Node)]

    def arg_pos(self, c):
        return _nest1(S.ArgPos(c[0].pos, c[0]), c[0])

    def arg_in(self, c):
        return _nest1(S.ArgIn(_pos(c[0]), str(c[0]).upper(), c[2]), c[2])

    def arg_out(self, c):
        return _nest1(S.ArgOut(_pos(c[0]), str(c[0]).upper(), c[2], False), c[2])

    def arg_out_not(self, c):
        return S.ArgOut(_pos(c[1]), str(c[1]).upper(), c[3], True)

    # ---- expressions
    def binop(self, c):
        return _nest2(S.BinOp(_pos(c[1]), str(c[1]).upper() if c[1].type != "AMP" else "AND", c[0], c[2]),
                      c[0], c[2])

    def neg(self, c):
        return _nest1(S.UnOp(_pos(c[0]), "-", c[1]), c[1])

    def pos(self, c):
        return _nest1(S.UnOp(_pos(c[0]), "+", c[1]), c[1])

    def not_(self, c):
        return _nest1(S.UnOp(_pos(c[0]), "NOT", c[1]), c[1])

    def int_lit(self, c):
        t = c[0]
        return S.IntLit(_pos(t), int_value(t), str(t), "#" in t)

    def real_lit(self, c):
        return S.RealLit(_pos(c[0]), float(str(c[0]).replace("_", "")), str(c[0]))

    def time_lit(self, c):
        t = str(c[0])
        return S.TimeLit(_pos(c[0]), parse_time(t.split("#", 1)[1]), t)

    def bool_lit(self, c):
        return S.BoolLit(_pos(c[0]), c[0].type == "TRUE")

    def string_lit(self, c):
        return S.StringLit(_pos(c[0]), str(c[0]))

    def typed_literal(self, c):
        prefix, sign, val = c
        tname = str(prefix)[:-1].upper()
        text = str(prefix) + (str(sign) if sign is not None else "") + str(val)
        neg = sign is not None and sign.type == "MINUS"
        if val.type in ("INTEGER", "BASED_INT"):
            v = int_value(val)
            if v is None:
                return S.TypedLit(_pos(prefix), tname, str(val), "bad", text)
            return S.TypedLit(_pos(prefix), tname, -v if neg else v, "int", text)
        if val.type == "REAL_LIT":
            v = float(str(val).replace("_", ""))
            return S.TypedLit(_pos(prefix), tname, -v if neg else v, "real", text)
        if val.type in ("TRUE", "FALSE"):
            return S.TypedLit(_pos(prefix), tname, val.type == "TRUE", "bool", text)
        return S.TypedLit(_pos(prefix), tname, str(val).upper(), "ident", text)

    def name(self, c):
        return S.Name(_pos(c[0]), str(c[0]).upper())

    def field(self, c):
        return _nest1(S.Field(_pos(c[2]), c[0], str(c[2]).upper()), c[0])

    def index(self, c):
        ixs = [x for x in c[2:-1] if isinstance(x, S.Node)]
        return _nest(S.Index(_pos(c[1]), c[0], ixs), c[0], ixs)

    def bit_access(self, c):
        return S.BitAccess(_pos(c[1]), c[0], str(c[2]))

    def deref(self, c):
        return S.Deref(_pos(c[1]), c[0])

    def func_call(self, c):
        return _nest(S.Call(_pos(c[0]), str(c[0]).upper(), c[2] or []), c[2] or [])

    def paren(self, c):
        return _nest1(S.Paren(_pos(c[0]), c[1]), c[1])

    def start(self, c):
        return list(c)


_TOKEN_TEXT = {
    "ASSIGN": "':='", "ARROW": "'=>'", "COLON": "':'", "SEMI": "';'", "COMMA": "','",
    "DOTDOT": "'..'", "DOT": "'.'", "LPAR": "'('", "RPAR": "')'", "LBRACK": "'['",
    "RBRACK": "']'", "AMP": "'&'", "EQ": "'='", "NE": "'<>'", "LT": "'<'", "GT": "'>'",
    "LE": "'<='", "GE": "'>='", "PLUS": "'+'", "MINUS": "'-'", "POW": "'**'", "STAR": "'*'",
    "SLASH": "'/'", "DEREF": "'^'", "IDENT": "an identifier", "INTEGER": "an integer",
    "BASED_INT": "an integer", "REAL_LIT": "a REAL literal", "TIME_LIT": "a TIME literal",
    "TYPED_PREFIX": "a typed literal", "DIRECT": "a direct address", "STRING_LIT": "a string",
    "$END": "end of file",
}

KEYWORDS = None  # filled from the grammar at load time


_KEYWORD_TYPES = {"ON", "AT", "TASK", "WITH", "CONTINUE", "EXIT", "RETURN", "BY", "TO", "DO", "OF",
                  "CONSTANT", "RETAIN", "NON_RETAIN", "THEN", "ELSE", "ELSIF", "UNTIL", "TYPE",
                  "ARRAY", "STRUCT", "PROGRAM", "FUNCTION", "FUNCTION_BLOCK", "RESOURCE",
                  "CONFIGURATION", "VAR", "IF", "CASE", "FOR", "WHILE", "REPEAT", "MOD", "NOT",
                  "AND", "OR", "XOR", "TRUE", "FALSE"}


_NAMEY = {"ON", "AT", "TASK", "WITH", "BY", "TO", "DO", "OF", "CONTINUE", "EXIT", "RETURN",
          "CONSTANT", "RETAIN", "NON_RETAIN", "TYPE", "MOD", "STRUCT", "ARRAY"}


def _describe(tok_type):
    if tok_type in _TOKEN_TEXT:
        return _TOKEN_TEXT[tok_type]
    return tok_type


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


class _Recovery:
    """Error recovery: report an error, then drop tokens until the parser can go on.

    A new error is only reported after the parser has consumed a ';' (or a block end)
    since the previous one, so one mistake does not produce a cascade of messages."""

    def __init__(self, report):
        self.report = report
        self.last_line = 0
        self.skipping = False

    def _new(self, line):
        # one message per line: the tokens dropped while recovering do not cascade
        if line > self.last_line:
            self.last_line = line
            return True
        return False

    def __call__(self, e):
        if isinstance(e, UnexpectedCharacters):
            if self._new(e.line):
                ch = e.char
                if ch == "'" or ch == '"':
                    msg = f"string literal not closed on its line: missing {ch}"
                else:
                    msg = f"unexpected character {ch!r}"
                self.report((e.line, e.column), msg)
            return True
        if isinstance(e, UnexpectedToken):
            tok = e.token
            pos = _tok_pos(tok, e)
            if tok.type == "$END" or self._new(pos[0]):
                self.report(pos, _unexpected_message(e))
            if tok.type == "$END":
                return False
            if self.skipping:
                if tok.type == "SEMI":
                    self.skipping = False
                return True
            # a missing ';' is the commonest slip: insert one when it lets the parser go on
            if "SEMI" in e.expected and tok.type != "SEMI":
                ip = e.interactive_parser
                try:
                    probe = ip.copy(deepcopy_values=False)  # reductions build new nodes only
                    probe.feed_token(Token("SEMI", ";", 0, tok.line, tok.column, tok.line, tok.column, 0))
                    probe.feed_token(tok)
                except UnexpectedInput:
                    pass
                else:
                    ip.feed_token(Token("SEMI", ";", 0, tok.line, tok.column, tok.line, tok.column, 0))
                    ip.feed_token(tok)
                    return True
            # panic mode: abandon the statement (or declaration) being parsed and skip to the
            # next ';'
            ps = e.interactive_parser.parser_state
            states = ps.parse_conf.parse_table.states
            stack = ps.state_stack
            depth = len(stack)
            while depth > 1:
                acts = states[stack[depth - 1]]
                if tok.type in acts or "IF" in acts or "END_VAR" in acts:
                    break
                depth -= 1
            if depth > 1:
                drop = len(stack) - depth
                if drop:
                    del stack[depth:]
                    del ps.value_stack[len(ps.value_stack) - drop:]
                if tok.type in states[stack[-1]]:
                    try:
                        e.interactive_parser.feed_token(tok)
                    except UnexpectedInput:
                        pass
                    return True
                if tok.type != "SEMI":
                    self.skipping = True
            return True
        return False


def _tok_pos(tok, e):
    line = getattr(tok, "line", None) or getattr(e, "line", None) or 0
    col = getattr(tok, "column", None) or getattr(e, "column", None) or 0
    if line == -1 or line is None:
        line, col = 0, 0
    return (line, col)


_END_ORDER = ["END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT", "END_VAR", "END_STRUCT",
              "END_TYPE", "END_FUNCTION", "END_FUNCTION_BLOCK", "END_PROGRAM", "END_RESOURCE",
              "END_CONFIGURATION"]
_STMT_START = {"IDENT", "IF", "CASE", "FOR", "WHILE", "REPEAT", "EXIT", "CONTINUE", "RETURN"}


def _unexpected_message(e):
    tok = e.token
    exp = set(e.expected)
    prev = None
    try:
        top = e.interactive_parser.parser_state.value_stack[-1]
        if isinstance(top, Token):
            prev = top
        elif isinstance(top, S.NamedType) and tok.type in ("IDENT", "TO"):
            prev = Token("IDENT", top.name)
    except (AttributeError, IndexError):
        pass
    if tok.type == "$END":
        for x in ("END_PROGRAM", "END_FUNCTION_BLOCK", "END_FUNCTION"):
            if x in exp:
                return f"unexpected end of file: missing {x}"
        for x in _END_ORDER:
            if x in exp:
                return f"unexpected end of file: missing {x}"
        return "unexpected end of file"
    if prev is not None and prev.type == "IDENT" and str(prev).upper() in ("POINTER", "REF_TO", "REF"):
        return f"{str(prev).upper()} is not portable (matiec rejects pointers and references)"
    if prev is not None and str(prev).upper() == "METHOD" or tok.type == "IDENT" and str(tok).upper() == "METHOD":
        return "METHOD is not portable (matiec rejects it): use a separate FUNCTION_BLOCK or FUNCTION"
    if (prev is not None and prev.type in _KEYWORD_TYPES and tok.type in ("COLON", "ASSIGN", "COMMA")
            and prev.type not in ("END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT")):
        return f"'{prev}' is a reserved keyword and cannot be used as an identifier"
    text = str(tok)
    if tok.type == "IDENT":
        what = f"identifier '{text}'"
    elif tok.type in _TOKEN_TEXT:
        what = f"'{text}'"
    else:
        what = f"'{text}'"
        if "IDENT" in exp and tok.type in _NAMEY:
            return (f"'{text}' is a reserved keyword and cannot be used as an identifier"
                    if tok.type not in ("TRUE", "FALSE") else f"unexpected {what}")
    if "SEMI" in exp and (len(exp) <= 3 or tok.type in _STMT_START):
        if prev is not None and prev.type in ("END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT"):
            return f"missing ';' after {prev.type} (matiec requires it) before {what}"
        return f"expected ';' before {what}"
    if {"INTEGER", "IDENT", "LPAR"} <= exp:
        return f"unexpected {what}, expected an expression"
    if tok.type == "COLON" and "ASSIGN" in exp:
        return f"unexpected ':' (did you mean ':='?)"
    shown = sorted(_describe(x) for x in exp)
    if len(shown) <= 6 and shown:
        return f"unexpected {what}, expected " + " or ".join(shown)
    return f"unexpected {what}"


def parse(text, filename, diags, dialect="st"):
    """Parse one file; syntax errors go to diags. Returns a list of top-level nodes.
    dialect "scl": TIA Portal SCL, rewritten to ST in place first (scl_in.py); "twincat" /
    "codesys": the IDE's ST, rewritten the same way (vendor_in.py)."""
    p = _get_parser()
    errors = []

    def report(pos, msg):
        diags.error(filename, pos, msg)
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
        _pos(tok), ("//" if tok.startswith("//") else "/* */")
        + " comments are not portable (matiec rejects them): use (* ... *)")
    _comment_sink[1] = lambda tok: report(
        _pos(tok), "{ ... } pragmas are not portable (matiec pastes them into its C output): "
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
        report((line, col), "PERSISTENT is CODESYS/TwinCAT, not IEC 61131-3 (matiec rejects it): "
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
            report(pos if pos[0] > 0 else (0, 0), _unexpected_message(e) if tok is not None else "syntax error")
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
            report(where(start), f"{what} is not closed: missing '{close}'")
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
                    report(where(inner), "nested comments are not portable (matiec rejects "
                           "them without -n): close the outer comment first")
                    rec.last_line = max(rec.last_line, where(end)[0])
        elif tok == "/*":
            report(where(start), "/* */ comments are not portable (matiec rejects them): "
                   "use (* ... *)")
        else:
            report(where(start), "{ ... } pragmas are not portable (matiec pastes them into its "
                   "C output): remove it or make it a (* comment *)")
        out.append(text[pos:start])
        out.append(_NOT_NL.sub(lambda x: " " * len(x.group(0)), text[start:end]))
        pos = scan = end
    out.append(text[pos:])
    return "".join(out)
