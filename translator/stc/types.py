"""IEC types, their C storage, and the standard library signatures stc knows."""


class Type:
    __slots__ = ()
    is_elem = is_array = is_struct = is_enum = is_fb = is_lit = False


class Elem(Type):
    """An elementary type. kind: bool bit sint uint real time."""
    __slots__ = ("name", "kind", "bits", "ctype", "default")
    is_elem = True

    def __init__(self, name, kind, bits, ctype, default=None):
        self.name, self.kind, self.bits, self.ctype, self.default = name, kind, bits, ctype, default

    def with_default(self, default):
        return Elem(self.name, self.kind, self.bits, self.ctype, default)

    def __str__(self):
        return self.name

    @property
    def is_int(self):
        return self.kind in ("sint", "uint")

    @property
    def is_anybit(self):
        return self.kind in ("bit", "bool")

    @property
    def is_num(self):
        return self.kind in ("sint", "uint", "real")

    @property
    def signed(self):
        return self.kind == "sint"

    def range(self):
        if self.kind == "sint":
            return -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        if self.kind in ("uint", "bit", "bool"):
            return 0, (1 << self.bits) - 1 if self.kind != "bool" else 1
        return None


class ArrayT(Type):
    __slots__ = ("elem", "dims", "name", "default")
    is_array = True

    def __init__(self, elem, dims, name=None, default=None):
        self.elem, self.dims, self.name, self.default = elem, dims, name, default

    def count(self):
        n = 1
        for lo, hi in self.dims:
            n *= hi - lo + 1
        return n

    def __str__(self):
        if self.name:
            return self.name
        d = ",".join(f"{lo}..{hi}" for lo, hi in self.dims)
        return f"ARRAY[{d}] OF {self.elem}"


class StructT(Type):
    __slots__ = ("name", "fields", "default")   # fields: {NAME: (type, init, pos)}
    is_struct = True

    def __init__(self, name, fields, default=None):
        self.name, self.fields, self.default = name, fields, default

    def __str__(self):
        return self.name


class EnumT(Type):
    __slots__ = ("name", "values", "default", "codes")
    is_enum = True

    def __init__(self, name, values, default=None, codes=None):
        self.name, self.values, self.default = name, values, default
        self.codes = codes     # explicit values (A := 51) of the vendor dialects, else None

    def code(self, value):
        """The number of an enumerated value: its position, or its explicit value."""
        i = self.values.index(value)
        return self.codes[i] if self.codes else i

    def __str__(self):
        return self.name


class FBT(Type):
    __slots__ = ("name", "pou", "default")
    is_fb = True

    def __init__(self, name, pou):
        self.name, self.pou, self.default = name, pou, None

    def __str__(self):
        return self.name


class LitT(Type):
    """The type of an untyped literal before the context fixes it: kind int / real."""
    __slots__ = ("kind",)
    is_lit = True

    def __init__(self, kind):
        self.kind = kind

    def __str__(self):
        return "an integer literal" if self.kind == "int" else "a REAL literal"


LIT_INT = LitT("int")
LIT_REAL = LitT("real")

ELEMENTARY = {}
for _n, _k, _b, _c in [
    ("BOOL", "bool", 1, "uint8_t"),
    ("BYTE", "bit", 8, "uint8_t"), ("WORD", "bit", 16, "uint16_t"),
    ("DWORD", "bit", 32, "uint32_t"), ("LWORD", "bit", 64, "uint64_t"),
    ("SINT", "sint", 8, "int8_t"), ("INT", "sint", 16, "int16_t"),
    ("DINT", "sint", 32, "int32_t"), ("LINT", "sint", 64, "int64_t"),
    ("USINT", "uint", 8, "uint8_t"), ("UINT", "uint", 16, "uint16_t"),
    ("UDINT", "uint", 32, "uint32_t"), ("ULINT", "uint", 64, "uint64_t"),
    ("REAL", "real", 32, "float"), ("LREAL", "real", 64, "double"),
    ("TIME", "time", 64, "stc_time"),
    ("STRING", "string", 8 * 127, "stc_string"),
]:
    ELEMENTARY[_n] = Elem(_n, _k, _b, _c)

BOOL = ELEMENTARY["BOOL"]
TIME = ELEMENTARY["TIME"]
INT = ELEMENTARY["INT"]
DINT = ELEMENTARY["DINT"]
LINT = ELEMENTARY["LINT"]

# types whose *_TO_* conversions stc provides
CONVERTIBLE = ["BOOL", "BYTE", "WORD", "DWORD", "LWORD", "SINT", "INT", "DINT", "LINT",
               "USINT", "UINT", "UDINT", "ULINT", "REAL", "LREAL", "TIME"]

# types matiec knows but stc does not implement
UNSUPPORTED_TYPES = {"WSTRING", "DATE", "TIME_OF_DAY", "TOD", "DATE_AND_TIME", "DT",
                     "LTIME", "LDATE", "LTOD", "LDT", "CHAR", "WCHAR"}


class PointerT(Elem):
    """POINTER TO target (the TwinCAT / CODESYS dialects only; matiec has no pointers): stored
    as a C `void *`; kind "ptr" so no arithmetic, conversion or literal rule applies to it."""
    __slots__ = ("target",)

    def __init__(self, target):
        super().__init__(f"POINTER TO {target}", "ptr", 64, "void *")
        self.target = target

    def with_default(self, default):
        return self


def same_type(a, b, array_names=True):
    """IEC type equality. Arrays are equal only when both are of the same named TYPE (matiec
    rejects assigning or passing anonymous ARRAY[..] OF .. even with identical bounds), unless
    array_names is False (structural: the VAR_EXTERNAL check tells a shape mismatch apart from
    two anonymous arrays of one shape)."""
    if isinstance(a, PointerT) or isinstance(b, PointerT):
        # as TwinCAT and CODESYS: any pointer takes any pointer (ADR's result, PVOID)
        return isinstance(a, PointerT) and isinstance(b, PointerT)
    if a.is_elem and b.is_elem:
        return a.name == b.name
    if a.is_array and b.is_array:
        if array_names:
            return a.name is not None and a.name == b.name
        return a.dims == b.dims and same_type(a.elem, b.elem, False)
    if a is b:
        return True
    if a.is_struct and b.is_struct or a.is_enum and b.is_enum or a.is_fb and b.is_fb:
        return a.name == b.name
    return False


class StdFB:
    """A standard function block implemented in the generated header (stc_rt.h)."""

    def __init__(self, name, inputs, outputs):
        self.name = name
        self.inputs = inputs      # [(NAME, typename)]
        self.outputs = outputs
        self.needs_time = name in ("TON", "TOF", "TP")


STD_FBS = {fb.name: fb for fb in [
    StdFB("TON", [("IN", "BOOL"), ("PT", "TIME")], [("Q", "BOOL"), ("ET", "TIME")]),
    StdFB("TOF", [("IN", "BOOL"), ("PT", "TIME")], [("Q", "BOOL"), ("ET", "TIME")]),
    StdFB("TP", [("IN", "BOOL"), ("PT", "TIME")], [("Q", "BOOL"), ("ET", "TIME")]),
    StdFB("R_TRIG", [("CLK", "BOOL")], [("Q", "BOOL")]),
    StdFB("F_TRIG", [("CLK", "BOOL")], [("Q", "BOOL")]),
    StdFB("CTU", [("CU", "BOOL"), ("R", "BOOL"), ("PV", "INT")], [("Q", "BOOL"), ("CV", "INT")]),
    StdFB("CTD", [("CD", "BOOL"), ("LD", "BOOL"), ("PV", "INT")], [("Q", "BOOL"), ("CV", "INT")]),
    StdFB("CTUD", [("CU", "BOOL"), ("CD", "BOOL"), ("R", "BOOL"), ("LD", "BOOL"), ("PV", "INT")],
          [("QU", "BOOL"), ("QD", "BOOL"), ("CV", "INT")]),
    StdFB("SR", [("S1", "BOOL"), ("R", "BOOL")], [("Q1", "BOOL")]),
    StdFB("RS", [("S", "BOOL"), ("R1", "BOOL")], [("Q1", "BOOL")]),
]}

# generic standard functions handled by the checker (names are reserved as identifiers)
STD_FUNCS = {"ABS", "MIN", "MAX", "LIMIT", "SEL", "MUX", "SHL", "SHR", "ROL", "ROR", "MOVE",
             "ADD", "SUB", "MUL", "DIV", "SQRT", "EXPT", "TRUNC", "LN", "LOG", "EXP",
             "LEN", "CONCAT", "LEFT", "RIGHT", "MID", "FIND", "INSERT", "DELETE", "REPLACE",
             "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"}

# the standard string functions: parameter names in order (STRING or integer)
STR_FUNCS = {"LEFT": ("IN", "L"), "RIGHT": ("IN", "L"), "MID": ("IN", "L", "P"),
             "FIND": ("IN1", "IN2"), "INSERT": ("IN1", "IN2", "P"), "DELETE": ("IN", "L", "P"),
             "REPLACE": ("IN1", "IN2", "L", "P")}

STRING = ELEMENTARY["STRING"]
STR_MAX = 126      # matiec's STR_MAX_LEN: characters a STRING holds

# names matiec refuses as identifiers (keywords it reserves and standard library names)
RESERVED = {"EN", "ENO", "STEP", "END_STEP", "ACTION", "END_ACTION", "TRANSITION",
            "END_TRANSITION", "FROM", "INITIAL_STEP", "TIME", "DT", "DATE", "TOD", "DATE_AND_TIME",
            "TIME_OF_DAY", "STRING", "WSTRING", "READ_ONLY", "READ_WRITE",
            "EXPT", "LEN", "LEFT", "RIGHT", "MID", "CONCAT", "INSERT", "DELETE",
            "REPLACE", "FIND", "SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS",
            "ATAN", "NE", "EQ", "GT", "GE", "LT", "LE", "NOT", "METHOD", "INTERFACE", "POINTER",
            "REF_TO", "NULL", "ANY", "ANY_NUM", "ANY_INT", "ANY_BIT", "ANY_REAL",
            "ANY_ELEMENTARY", "ANY_DERIVED", "ANY_MAGNITUDE", "ANY_DATE", "ANY_STRING"}
RESERVED |= set(ELEMENTARY) | STD_FUNCS | set(STD_FBS) | UNSUPPORTED_TYPES
