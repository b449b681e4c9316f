"""POU interfaces, variable blocks, located variables, the CONFIGURATION and its globals."""
import re

from .. import syntax as S
from .. import types as T
from ..diag import CompileError
from .project import ConfigInfo, Instance, ResourceInfo, Task, Var
from .helpers import _addr_text

# the variable blocks each kind of POU may declare
_KIND_OK = {
    "function": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP"},
    "function_block": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP", "VAR_EXTERNAL"},
    "program": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP", "VAR_EXTERNAL"},
}


class DeclarationChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

    # ---- POU declarations
    def _declare_pou(self, pou):
        n = pou.node
        if isinstance(n, S.Function):
            try:
                pou.rtype = self.resolve_type(n.rtype)
            except CompileError:
                pou.rtype = T.INT
            if pou.rtype.is_fb:
                self.err(n.rtype.pos, "S0201", "a FUNCTION cannot return a function block")
            elif pou.rtype.is_struct:
                self.err(n.rtype.pos, "S0202", "a FUNCTION returning a STRUCT is not supported by stc: "
                         "use a VAR_IN_OUT or a FUNCTION_BLOCK")
            elif pou.rtype.is_array and pou.rtype.name is None:
                self.err(n.rtype.pos, "S0203", "a FUNCTION returning an anonymous ARRAY cannot be "
                         "assigned anywhere (matiec rejects assigning anonymous ARRAY types): "
                         "declare a named array TYPE and return that")
        for blk in n.blocks:
            self._var_block(pou, blk)

    def _var_block(self, pou, blk, where=None):
        kind = blk.kind
        allowed = _KIND_OK[pou.kind] if pou is not None else {"VAR_GLOBAL"}
        if kind not in allowed:
            if kind == "VAR_GLOBAL":
                self.err(blk.pos, "S0204", f"VAR_GLOBAL is not allowed in a {pou.kind.replace('_', ' ').upper()}: "
                         "declare it in the CONFIGURATION or RESOURCE and use VAR_EXTERNAL")
            elif kind == "VAR_EXTERNAL":
                self.err(blk.pos, "S0205", "VAR_EXTERNAL is not allowed in a FUNCTION: pass the value as "
                         "VAR_INPUT or VAR_IN_OUT")
            else:
                self.err(blk.pos, "S0206", f"{kind} is not allowed here")
            return
        constant = "CONSTANT" in blk.quals
        retain = "RETAIN" in blk.quals
        if len(blk.quals) > 1:
            self.err(blk.pos, "S0207", f"{kind} {' '.join(blk.quals)}: one qualifier per block is "
                     "portable (matiec rejects more)")
        elif blk.quals and blk.quals[0] != "CONSTANT" and (
                kind not in ("VAR", "VAR_INPUT", "VAR_OUTPUT", "VAR_GLOBAL")
                or (pou is not None and pou.kind == "function")):
            where_ = "in a FUNCTION" if pou is not None and pou.kind == "function" else f"on {kind}"
            self.err(blk.pos, "S0208", f"{blk.quals[0]} is not allowed {where_} (matiec rejects it)")
        elif blk.quals == ["NON_RETAIN"] and kind == "VAR_GLOBAL":
            self.err(blk.pos, "S0209", "NON_RETAIN is not allowed on VAR_GLOBAL (matiec rejects it): "
                     "a VAR_GLOBAL without a qualifier is not retained")
        if constant and kind not in ("VAR", "VAR_GLOBAL", "VAR_EXTERNAL"):
            self.err(blk.pos, "S0210", f"CONSTANT is not allowed on {kind}")
        located = [d for d in blk.decls if d.location is not None]
        # matiec (upstream and OpenPLC's fork) accepts the mix in a VAR_GLOBAL of a
        # CONFIGURATION or RESOURCE and rejects it in a POU's VAR block
        if located and len(located) != len(blk.decls) and kind != "VAR_GLOBAL":
            self.err(blk.pos, "S0211", "located and unlocated variables in one VAR block are not portable "
                     "(matiec rejects it): put the AT variables in a VAR block of their own")
        target = pou.vars if pou is not None else where
        for d in blk.decls:
            try:
                ty = self.resolve_type(d.type)
            except CompileError:
                continue
            if not d.names:
                self.err(d.pos, "S0212", "a located variable needs a name (matiec rejects 'AT %... :' "
                         "without one)")
                continue
            for name, npos in d.names:
                self._check_ident(name, npos)
                if name in target:
                    self.err(npos, "S0101", f"'{name}' is declared twice")
                    continue
                if pou is not None and name == pou.name:
                    self.err(npos, "S0213", f"'{name}' is the name of the POU")
                if name in self.p.pous:
                    self.err(npos, "S0214", f"'{name}' is already the name of a POU")
                v = Var(name, kind, ty, d.init, npos, self.file)
                v.constant, v.retain, v.owner = constant, retain, pou
                if ty.is_fb:
                    if pou is not None and pou.kind == "function":
                        self.err(npos, "S0215", "a function block instance inside a FUNCTION is not "
                                 "portable (matiec rejects it): use a FUNCTION_BLOCK")
                    if kind == "VAR_IN_OUT" and not self.dialect.fb_in_out:
                        self.err(npos, "S0216", "VAR_IN_OUT of a function block type is not portable "
                                 "(it crashes matiec)")
                    if kind in ("VAR_INPUT", "VAR_OUTPUT") and pou is not None and pou.kind == "function":
                        self.err(npos, "S0217", "a function block cannot be a FUNCTION parameter")
                    if constant:
                        self.err(npos, "S0218", "a function block instance cannot be CONSTANT")
                if d.location is not None:
                    self._located(v, d.location, pou)
                if d.init is not None:
                    if kind == "VAR_IN_OUT" or kind == "VAR_EXTERNAL":
                        self.err(d.init.pos, "S0219", f"{kind} variables cannot have an initial value")
                    elif ty.is_fb:
                        self.err(d.init.pos, "S0220", "function block instances cannot have an initial value")
                    else:
                        self.check_init(d.init, ty)
                if constant and d.init is None and kind != "VAR_EXTERNAL":
                    self.err(npos, "S0221", f"CONSTANT '{name}' needs an initial value")
                if (pou is not None and pou.kind == "function" and kind == "VAR_INPUT"
                        and ty.is_array):
                    self.err(npos, "S0222", "a FUNCTION with an array VAR_INPUT compiles with matiec but "
                             "its C does not: use VAR_IN_OUT")
                target[name] = v

    _LOC_RE = re.compile(r"^%([IQM])([XBWDL]?)([0-9]+(?:\.[0-9]+)*)$")
    _SIZE = {"X": 1, "B": 8, "W": 16, "D": 32, "L": 64}

    def _located(self, v, loc, pou):
        text, pos = loc
        located_fb = pou is not None and pou.kind == "function_block" and self.dialect.located_in_fb
        if pou is not None and pou.kind != "program" and not located_fb:
            # (the vendor dialects: TwinCAT links an FB's AT %I* / %Q* in its I/O mapping; stc
            # takes full addresses there, one cell for every instance: the stand-ins' channel)
            self.err(pos, "S0223", f"located variables in a {pou.kind.upper()} are not "
                     "portable (matiec rejects them): declare them in the PROGRAM and pass them "
                     "as inputs/outputs")
            return
        if "*" in text:
            self.err(pos, "S0224", "'AT %I*' is not portable (matiec rejects it): give the full address")
            return
        m = self._LOC_RE.match(text)
        if not m:
            self.err(pos, "S0225", f"invalid direct address {text}")
            return
        area, size, addr = m.group(1), m.group(2) or "X", m.group(3)
        parts = [int(x) for x in addr.split(".")]
        if v.type.is_array:
            # matiec rejects it in a POU; in a VAR_GLOBAL it accepts an array of a named TYPE,
            # and stock OpenPLC's glue generator then binds only the first register to its I/O
            self.err(pos, "S0226", "a located ARRAY is not portable (matiec rejects it in a POU; stock "
                     "OpenPLC binds only its first register): declare one located variable "
                     "per address")
            return
        if not v.type.is_elem or v.type.kind in ("time", "real") and size in ("X", "B", "W"):
            if not v.type.is_elem:
                self.err(pos, "S0227", f"a located variable must be of an elementary type, not {v.type}")
                return
        if v.type.is_elem and v.type.kind != "time":
            bits = v.type.bits
            if (size == "X") != (bits == 1) or size != "X" and self._SIZE[size] != bits:
                self.err(pos, "S0228", f"{v.type} does not fit address {text} ({self._SIZE[size]} bit)")
                return
        elif v.type.kind == "time":
            self.err(pos, "S0229", "a located TIME variable is not supported")
            return
        if size == "X" and len(parts) != 2:
            self.err(pos, "S0230", f"a bit address needs byte.bit, like %{area}X0.0")
            return
        if size != "X" and len(parts) != 1:
            self.err(pos, "S0225", f"invalid direct address {text}")
            return
        if size == "X" and not 0 <= parts[1] <= 7:
            self.warn(pos, "W0001", f"portability: bit number {parts[1]} is outside 0..7: matiec accepts "
                      "it, but OpenPLC's I/O image has 8 bits per byte, so nothing reaches it")
        v.location = (area, size, parts)
        v.cname = "__" + area + size + "_".join(str(x) for x in parts)
        v.pos = v.pos
        self.p.located.append(v)

    def _check_located(self):
        seen = {}
        for v in self.p.located:
            if v.cname in seen:
                first = seen[v.cname]
                self.err(v.pos, "S0231", f"address {_addr_text(v)} is already used by '{first.name}' "
                         f"({first.file}:{first.pos[0]}): matiec rejects an address used twice",
                         v.file)
            else:
                seen[v.cname] = v

    # ---- configuration
    def _configuration(self, c):
        cfg = ConfigInfo(c.name)
        self.p.config = cfg
        self._check_ident(c.name, c.pos)
        for blk in c.blocks:
            self._global_block(blk, cfg.globals, cfg.name)
        resources = list(c.resources)
        if c.tasks or c.progs:
            if resources:
                self.err(c.pos, "S0232", "tasks and programs belong inside the RESOURCE")
            else:
                # single resource configuration
                resources = [S.Resource(c.pos, "RESOURCE1", "PLC", [], c.tasks, c.progs)]
        if not resources:
            self.err(c.pos, "S0233", f"CONFIGURATION {c.name} has no RESOURCE")
        names = set()
        for r in resources:
            ri = ResourceInfo(r.name)
            if r.name in self.p.pous or r.name in self.p.types:
                self.err(r.pos, "S0234", f"resource '{r.name}' has the name of a POU or type")
            if r.name in names:
                self.err(r.pos, "S0235", f"resource '{r.name}' is declared twice")
            names.add(r.name)
            self._check_ident(r.name, r.pos)
            cfg.resources.append(ri)
            for blk in r.blocks:
                self._global_block(blk, ri.globals, f"{cfg.name}.{ri.name}")
            tasks = {}
            for t in r.tasks:
                self._check_ident(t.name, t.pos)
                interval, prio = None, 0
                for pn, pv, ppos in t.params:
                    if pn == "INTERVAL":
                        self.scope, self.cur = {}, None
                        try:
                            ty = self.expr(pv, T.TIME)
                            if not (ty.is_elem and ty.kind == "time") or not isinstance(pv, S.TimeLit):
                                self.fail(pv.pos, "S0236", "INTERVAL must be a TIME literal like T#20ms")
                            interval = pv.ns
                        except CompileError:
                            pass
                    elif pn == "PRIORITY":
                        if not isinstance(pv, S.IntLit):
                            self.err(pv.pos, "S0237", "PRIORITY must be an integer")
                        else:
                            prio = pv.value
                    elif pn == "SINGLE":
                        self.err(ppos, "S0238", "SINGLE (event) tasks are not supported by stc: use INTERVAL")
                    else:
                        self.err(ppos, "S0239", f"unknown task parameter '{pn}'")
                if not any(pn == "PRIORITY" for pn, _, _ in t.params):
                    self.err(t.pos, "S0240", f"task {t.name} needs PRIORITY := n (matiec rejects a TASK "
                             "without it)")
                if interval is not None and interval <= 0:
                    self.err(t.pos, "S0241", "task INTERVAL must be positive")
                    interval = None
                if interval is None and not any(pn == "SINGLE" for pn, _, _ in t.params):
                    self.err(t.pos, "S0242", f"task {t.name} needs INTERVAL := T#...")
                if t.name in tasks:
                    self.err(t.pos, "S0243", f"task '{t.name}' is declared twice")
                task = Task(t.name, interval or 1, prio, t.pos)
                tasks[t.name] = task
                ri.tasks.append(task)
            inames = set()
            for pc in r.progs:
                self._check_ident(pc.name, pc.pos)
                if pc.name in inames:
                    self.err(pc.pos, "S0244", f"program instance '{pc.name}' is declared twice")
                inames.add(pc.name)
                pou = self.p.pous.get(pc.type)
                if pou is None or pou.kind != "program":
                    self.err(pc.pos, "S0245", f"'{pc.type}' is not a PROGRAM")
                    continue
                if pc.args:
                    self.err(pc.pos, "S0246", "program instance arguments are not supported by stc: use "
                             "VAR_GLOBAL and VAR_EXTERNAL")
                task = None
                if pc.task is not None:
                    task = tasks.get(pc.task)
                    if task is None:
                        self.err(pc.pos, "S0247", f"unknown task '{pc.task}'")
                ri.instances.append(Instance(pc.name, pou, task, ri))

    def _global_block(self, blk, target, owner):
        if blk.kind != "VAR_GLOBAL":
            self.err(blk.pos, "S0248", f"{blk.kind} is not allowed in a CONFIGURATION or RESOURCE: use VAR_GLOBAL")
            return
        before = set(target)
        self._var_block(None, blk, target)
        for name, v in target.items():
            if name in before:
                continue
            v.owner = owner
            if v.type.is_fb:
                self.err(v.pos, "S0249", "a function block instance as VAR_GLOBAL is not supported by stc")
            if v.location is None:
                v.cname = owner.replace(".", "__") + "__" + name

    def _bind_external(self, v):
        cands = []
        cfg = self.p.config
        if cfg is not None:
            if v.name in cfg.globals:
                cands.append(cfg.globals[v.name])
            for r in cfg.resources:
                if v.name in r.globals:
                    cands.append(r.globals[v.name])
        if not cands:
            self.err(v.pos, "S0250", f"VAR_EXTERNAL '{v.name}' has no VAR_GLOBAL of that name in the "
                     "configuration")
            return
        if len(cands) > 1:
            self.err(v.pos, "S0251", f"VAR_EXTERNAL '{v.name}' matches VAR_GLOBALs of several resources: "
                     "stc binds externals by name, give them distinct names")
            return
        g = cands[0]
        if not T.same_type(g.type, v.type, array_names=False):
            self.err(v.pos, "S0252", f"VAR_EXTERNAL '{v.name}' is {v.type} but the VAR_GLOBAL is {g.type}")
            return
        if not T.same_type(g.type, v.type):
            # matiec (both flavours): "Data type mismatch between external and global variable
            # declarations" for two anonymous ARRAY[..] OF .., even with the same bounds
            self.err(v.pos, "S0253", f"VAR_EXTERNAL '{v.name}' and its VAR_GLOBAL are anonymous ARRAYs: "
                     "not portable (matiec rejects it): declare a named array TYPE and use it "
                     "in both")
            return
        if g.constant and not v.constant:
            self.err(v.pos, "S0254", f"VAR_GLOBAL '{v.name}' is CONSTANT: declare the VAR_EXTERNAL CONSTANT too")
        v.glob = g
