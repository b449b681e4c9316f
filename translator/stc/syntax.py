"""Abstract syntax of the matiec ST dialect, built directly by the LALR parser callbacks."""


class Node:
    __slots__ = ("pos", "__dict__")   # __dict__: annotations added by the checker

    def __repr__(self):
        fields = ", ".join(f"{k}={getattr(self, k)!r}" for k in self.__slots__ if k != "pos")
        return f"{type(self).__name__}({fields})"


def _node(name, fields):
    fields = tuple(fields.split())

    def __init__(self, pos, *args):
        self.pos = pos
        for k, v in zip(fields, args):
            setattr(self, k, v)

    return type(name, (Node,), {"__slots__": fields, "__init__": __init__})


# positions are (line, column), both 1-based
# ---- types
NamedType = _node("NamedType", "name")                  # INT, MyStruct, TON
ArraySpec = _node("ArraySpec", "dims elem")             # dims: [(lo, hi)] ints or ConstBound
ConstBound = _node("ConstBound", "name")
SubrangeRef = _node("SubrangeRef", "base")
StringRef = _node("StringRef", "base size")
PointerRef = _node("PointerRef", "word target")        # POINTER TO T (vendor dialects)
StructSpec = _node("StructSpec", "members")             # members: [VarDecl]
EnumSpec = _node("EnumSpec", "items default")           # items: [(name, value_or_None, pos)]
TypeDef = _node("TypeDef", "name spec init")

# ---- declarations
VarDecl = _node("VarDecl", "names location type init")  # names: [(name, pos)]
VarBlock = _node("VarBlock", "kind quals decls")
Function = _node("Function", "name rtype blocks body end_pos")
FunctionBlock = _node("FunctionBlock", "name blocks body end_pos")
Program = _node("Program", "name blocks body end_pos")
TypeDecl = _node("TypeDecl", "defs")
Configuration = _node("Configuration", "name blocks resources tasks progs")
Resource = _node("Resource", "name target blocks tasks progs")
TaskConf = _node("TaskConf", "name params")             # params: [(name, expr, pos)]
ProgConf = _node("ProgConf", "name task type args")
StrayVarBlock = _node("StrayVarBlock", "block")

# ---- initialisers
ArrayInit = _node("ArrayInit", "items")                 # items: [(count_or_None, value_or_None)]
StructInit = _node("StructInit", "items")               # items: [(name, value, pos)]

# ---- statements
Assign = _node("Assign", "target value")
CallStmt = _node("CallStmt", "name args")
Empty = _node("Empty", "")
Exit = _node("Exit", "")
Continue = _node("Continue", "")
Return = _node("Return", "")
If = _node("If", "branches orelse")                     # branches: [(cond, stmts)], orelse None|list
Case = _node("Case", "selector items orelse")           # items flat: CaseLabels | stmt
CaseLabels = _node("CaseLabels", "labels")              # labels: [(lo, hi_or_None)] label nodes
For = _node("For", "var start end step body")
While = _node("While", "cond body")
Repeat = _node("Repeat", "body cond")

# ---- call arguments
ArgPos = _node("ArgPos", "value")
ArgIn = _node("ArgIn", "name value")
ArgOut = _node("ArgOut", "name target negate")

# ---- expressions (annotated by the checker: .ty)
class Expr(Node):
    __slots__ = ()


def _expr(name, fields):
    fields = tuple(fields.split()) + ("ty",)

    def __init__(self, pos, *args):
        self.pos = pos
        self.ty = None
        for k, v in zip(fields, args):
            setattr(self, k, v)

    return type(name, (Expr,), {"__slots__": fields, "__init__": __init__})


IntLit = _expr("IntLit", "value text based")
RealLit = _expr("RealLit", "value text")
TimeLit = _expr("TimeLit", "ns text")
BoolLit = _expr("BoolLit", "value")
StringLit = _expr("StringLit", "text")
TypedLit = _expr("TypedLit", "type_name value kind text")   # kind: int real bool ident
Name = _expr("Name", "name")
Field = _expr("Field", "base name")
Index = _expr("Index", "base indexes")
BitAccess = _expr("BitAccess", "base bit")
Deref = _expr("Deref", "base")
Call = _expr("Call", "name args")
BinOp = _expr("BinOp", "op left right")
UnOp = _expr("UnOp", "op operand")
Paren = _expr("Paren", "inner")
