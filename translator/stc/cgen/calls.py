"""Calls of functions, function blocks and the vendor dialects' functions."""
from .. import syntax as S
from .helpers import _body_eno, _c_elem, _own_copy, cdecl, lit


class CallGen:
    """A part of Gen (cgen/__init__.py): its methods call the other parts' through self."""

    def vendor_call(self, e):
        """ADR, SIZEOF, MEMCPY / SysMemCpy of the TwinCAT / CODESYS dialects."""
        if e.name == "ADR":
            return f"((void *)&{self.lv(e.argv[0])})"
        if e.name == "SIZEOF":
            return f"((uint32_t)sizeof {self.lv(e.argv[0])})"
        if e.name.startswith("TO_"):
            return f"(({e.ty.ctype}){self.ex(e.argv[0])})"
        d, s_, n = (self.ex(a) for a in e.argv)
        return f"stc_memcpy({d}, {s_}, {n})"

    def call_stmt(self, c):
        if getattr(c, "kind", None) == "fb":
            self.fb_call(c)
        elif getattr(c, "kind", None) == "vendor":
            e = S.Call(c.pos, c.name, c.args)
            e.kind, e.argv = c.kind, c.argv
            self.w(f"(void){self.vendor_call(e)};")
        else:
            e = S.Call(c.pos, c.name, c.args)
            for k in ("kind", "pou", "bound", "outs"):
                if hasattr(c, k):
                    setattr(e, k, getattr(c, k))
            if e.pou.rtype.is_array:
                tmp = self.new_tmp("res")
                self.w(f"{{ {e.pou.rtype.name} {tmp}; {self.func_call(e, result=tmp)}; }}")
            else:
                self.w(f"(void){self.func_call(e)};")

    def fb_call(self, c):
        v = c.var
        base = self.var_access(v)
        pou = v.type.pou
        copied = []
        for name, e in c.bound.items():
            p = pou.vars[name]
            if p.kind == "VAR_IN_OUT" and self.dialect.fb_in_out_copy and _own_copy(p):
                # matiec passes an FB's in-out by copy in and copy out: the instance keeps its
                # own copy, and a call that leaves the in-out out works on that copy alone
                self.w(f"memcpy(&{base}.{name}__COPY, &{self.lv(e)}, sizeof {base}.{name}__COPY);")
                self.w(f"{base}.{name} = &{base}.{name}__COPY;")
                copied.append((name, e))
            elif p.kind == "VAR_IN_OUT":
                self.w(f"{base}.{name} = &{self.lv(e)};")
            else:
                self.store(f"{base}.{name}", p.type, e)
        en = getattr(c, "en", None)
        eno = getattr(c, "eno", None)
        if en is not None:
            self.w(f"{base}.EN = (uint8_t)({self.ex(en)} != 0);")
        elif not self.dialect.en_keeps_last:
            self.w(f"{base}.EN = 1;")    # IEC: EN not given is TRUE (matiec keeps the last one)
        self.w(f"if ({base}.EN) {{")
        self.ind += 1
        self.w(f"{base}.ENO = 1;")
        if pou.std is not None and pou.std.needs_time:
            self.w(f"{pou.name}_body__(&{base}, stc_time_ns(__CURRENT_TIME));")
        else:
            self.w(f"{pou.name}_body__(&{base});")
        self.ind -= 1
        self.w("} else {")
        self.w(f"    {base}.ENO = 0;")
        self.w("}")
        if eno is not None:
            self.w(f"{self.lv(eno)} = {base}.ENO;")
        for name, e in copied:
            self.w(f"memcpy(&{self.lv(e)}, &{base}.{name}__COPY, sizeof {base}.{name}__COPY);")
        for p, target in c.outs:
            tl = self.lv(target)
            if p.type.is_array:
                self.w(f"memcpy(&{tl}, &{base}.{p.name}, sizeof {tl});")
            else:
                self.w(f"{tl} = {base}.{p.name};")

    def func_call(self, c, result=None):
        pou = c.pou
        args = [f"&{result}"] if result is not None else []
        outs = {p.name: t for p, t in c.outs}
        for v in pou.vars.values():
            if v.kind == "VAR_INPUT":
                e = c.bound.get(v.name)
                if e is None:
                    args.append(self.default_value(v))
                elif v.type.is_elem and v.type.kind == "time":
                    args.append(self.ex(e) if self.dialect.time_as_pair else f"stc_time_of({self.ex(e)})")
                elif v.type.is_struct or v.type.is_array:
                    args.append(self.lv(e))
                else:
                    args.append(self.ex(e))
            elif v.kind == "VAR_IN_OUT":
                e = c.bound.get(v.name)
                args.append(f"&{self.lv(e)}" if e is not None else "0")
            elif v.kind == "VAR_OUTPUT":
                t = outs.get(v.name)
                if t is not None:
                    args.append(f"&{self.lv(t)}")
                else:
                    args.append(f"&({cdecl(v.type, '')}){{0}}")
        en = getattr(c, "en", None)
        eno = getattr(c, "eno", None)
        body_eno = _body_eno(pou)
        if body_eno:
            args.append(f"&{self.lv(eno)}" if eno is not None else "&(uint8_t){0}")
        call = f"{pou.name}({', '.join(args)})"
        if en is None and (eno is None or body_eno):
            return call
        # EN := cond: the function runs only when cond is TRUE, otherwise its result is the
        # initial value of its type (matiec); ENO => v tells whether it ran
        rt = pou.rtype
        zero = "0" if rt is None else self.default_value(pou.result_var) \
            if getattr(pou, "result_var", None) is not None else self._zero(rt)
        if rt is not None and rt.is_elem and rt.kind == "time" and not self.dialect.time_as_pair:
            zero = "stc_time_of(INT64_C(0))"   # the call returns stc_time; see _ex
        set1 = f"{self.lv(eno)} = 1, " if eno is not None and not body_eno else ""
        set0 = f"{self.lv(eno)} = 0, " if eno is not None else ""
        if en is None:
            return f"({set1}{call})"
        return f"(({self.ex(en)}) ? ({set1}{call}) : ({set0}{zero}))"

    def default_value(self, v):
        t = v.type
        init = v.init if v.init is not None else getattr(t, "default", None)
        if t.is_elem and t.kind == "time":
            if self.dialect.time_as_pair:
                return self.ex(init) if isinstance(init, S.Expr) else "stc_mt_of(INT64_C(0))"
            return f"stc_time_of({self.ex(init) if isinstance(init, S.Expr) else 'INT64_C(0)'})"
        if isinstance(init, S.Expr):
            return self.ex(init)
        if t.is_enum:
            return f"{t.name}__{t.default}" if t.default else "0"
        if t.is_elem:
            return lit(0, t)
        return f"({_c_elem(t)}){{0}}"
