"""Semantic analysis: declarations, IEC strict typing, and the matiec dialect's restrictions.

The checker annotates expressions with `.ty` and collects everything the code generator needs in
a `Project`. Every error goes to the diagnostics with its position; analysis goes on after an
error so that one run reports as much as it can.

The checker is one class put together from one part per concern (names.py, declarations.py,
statements.py, expressions.py, coercion.py, calls.py, stdlib.py); this module holds its state,
its diagnostics and the order of the passes (run)."""
from .. import syntax as S
from ..diag import CompileError
from ..semantics import dialect
from .calls import CallChecks
from .coercion import CoercionChecks
from .declarations import DeclarationChecks
from .expressions import ExpressionChecks
from .names import TypeChecks
from .project import ConfigInfo, Instance, Pou, Project, ResourceInfo, Task, Var
from .statements import StatementChecks
from .stdlib import StdlibChecks

__all__ = ["Checker", "ConfigInfo", "Instance", "Pou", "Project", "ResourceInfo", "Task", "Var"]


class Checker(TypeChecks, DeclarationChecks, StatementChecks, ExpressionChecks, CoercionChecks, CallChecks, StdlibChecks):
    def __init__(self, diags, semantics="matiec", strict_iec=False):
        self.d = diags
        self.p = Project()
        self.p.semantics = semantics
        self.strict_iec = strict_iec   # --strict-iec: warn where an edition-2 checker is stricter
        self.file = None
        self.dialects = {}             # file -> its semantics.Dialect (compiler.py); else ST's
        self._st = dialect("st", semantics)

    @property
    def dialect(self):
        """The rules of the file being checked (stc/semantics.py): the checker asks them, it
        never tests a dialect's name."""
        return self.dialects.get(self.file, self._st)

    def warn(self, pos, code, msg):
        """Portability warning: the construct's value differs between matiec and IEC. code:
        its entry in problems.csv."""
        self.d.warn(self.file, pos, msg, code)
        self.note(pos, "warned", msg.replace("portability: ", "", 1))

    def note(self, pos, kind, text):
        """A construct on the divergence list (stc --divergences lists them)."""
        self.p.divergences.append((self.file, pos, kind, text))

    # ---- errors
    def err(self, pos, code, msg, file=None):
        """An error at pos; code: its entry in problems.csv (stc/problems.py)."""
        self.d.error(file or self.file, pos, msg, code)

    def fail(self, pos, code, msg):
        self.err(pos, code, msg)
        raise CompileError(msg)

    # ---- entry
    def run(self, files):
        """files: [(filename, [top-level nodes])]"""
        # pass 1: names of types and POUs, so declaration order does not matter
        for fname, nodes in files:
            self.file = fname
            for n in nodes:
                if isinstance(n, S.TypeDecl):
                    for td in n.defs:
                        self._declare_name(td.name, td.pos, "type")
                        self.p.types[td.name] = None
                        self.p.type_files[td.name] = (fname, td)
                elif isinstance(n, (S.Function, S.FunctionBlock, S.Program)):
                    kind = {S.Function: "function", S.FunctionBlock: "function_block",
                            S.Program: "program"}[type(n)]
                    if self._declare_name(n.name, n.pos, kind):
                        self.p.pous[n.name] = Pou(kind, n.name, n, fname)
                elif isinstance(n, S.StrayVarBlock):
                    self.err(n.pos, "S0001", f"{n.block.kind} outside a POU: global variables belong in a "
                             "CONFIGURATION or RESOURCE")
        # pass 2: resolve named types
        self._resolving = set()
        for name in list(self.p.types):
            self._resolve_named(name)
        # pass 3: POU interfaces
        for pou in self.p.pous.values():
            self.file = pou.file
            self._declare_pou(pou)
        # configuration (binds globals, needed before bodies for VAR_EXTERNAL)
        configs = [(f, n) for f, nodes in files for n in nodes if isinstance(n, S.Configuration)]
        for i, (fname, c) in enumerate(configs):
            self.file = fname
            if i > 0:
                self.err(c.pos, "S0002", "only one CONFIGURATION per build is supported")
                continue
            self._configuration(c)
        # bind externals
        for pou in self.p.pous.values():
            self.file = pou.file
            for v in pou.vars.values():
                if v.kind == "VAR_EXTERNAL":
                    self._bind_external(v)
        # pass 4: bodies
        for pou in self.p.pous.values():
            self.file = pou.file
            self._body(pou)
        self._check_located()
        return self.p

    _SEEN_KINDS = {}
