"""What the checker collects for the code generator: variables, POUs, tasks, the configuration."""


class Var:
    __slots__ = ("name", "kind", "type", "init", "constant", "retain", "location", "pos",
                 "file", "cname", "glob", "owner")

    def __init__(self, name, kind, type_, init, pos, file):
        self.name, self.kind, self.type, self.init, self.pos, self.file = name, kind, type_, init, pos, file
        self.constant = self.retain = False
        self.location = None       # (area, size, parts) for located variables
        self.cname = None          # C name of located pointer / global
        self.glob = None           # for VAR_EXTERNAL: the bound Var (VAR_GLOBAL)
        self.owner = None          # owning Pou / configuration / resource


class Pou:
    def __init__(self, kind, name, node, file):
        self.kind = kind           # function function_block program
        self.name = name
        self.node = node
        self.file = file
        self.vars = {}             # NAME -> Var, declaration order
        self.rtype = None
        self.std = None            # StdFB for standard function blocks
        self.used_now = False


class Task:
    def __init__(self, name, interval_ns, priority, pos):
        self.name, self.interval_ns, self.priority, self.pos = name, interval_ns, priority, pos


class Instance:
    def __init__(self, name, pou, task, resource):
        self.name, self.pou, self.task, self.resource = name, pou, task, resource


class ResourceInfo:
    def __init__(self, name):
        self.name = name
        self.globals = {}
        self.tasks = []
        self.instances = []


class ConfigInfo:
    def __init__(self, name):
        self.name = name
        self.globals = {}
        self.resources = []


class Project:
    def __init__(self):
        self.types = {}            # NAME -> Type (named types in declaration order)
        self.type_files = {}
        self.pous = {}             # NAME -> Pou, declaration order
        self.std_pous = {}         # standard FBs in use
        self.config = None
        self.located = []          # Var of every located variable, in declaration order
        self.enum_values = {}      # VALUE -> [EnumT] for bare enum names
        self.semantics = "matiec"  # "matiec", "openplc" or "iec": run-time values the C reproduces
        # (file, (line, col), kind, text): every construct on the divergence list (matiec,
        # OpenPLC's fork and IEC may give other values), warned or not: stc --divergences
        self.divergences = []
