"""The parser's callbacks: lark tokens and rules -> syntax.* nodes (run inline by the LALR
parser, see parser.py), with the literal values and the nesting depth check."""
import re

from lark import Token, Transformer

from . import syntax as S


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
        _depth_sink[0](node.pos, "P0109", f"nested too deeply (more than {MAX_DEPTH} levels of "
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
        direct = c[i + 1]
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

