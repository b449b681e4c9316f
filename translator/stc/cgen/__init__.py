"""C code generation from a checked Project (runtime ABI of docs/dev/interfaces.md section 1).

The generator is one class put together from one part per output concern (declarations.py,
statements.py, calls.py, expressions.py, runtime_files.py); this module holds its state, the
output buffer and the list of files it writes (generate)."""
import contextlib
import os

from ..semantics import dialect
from .calls import CallGen
from .declarations import DeclarationGen
from .expressions import ExpressionGen
from .helpers import HEADER
from .runtime_files import RuntimeFilesGen
from .statements import StatementGen

__all__ = ["Gen"]


class Gen(DeclarationGen, StatementGen, CallGen, ExpressionGen, RuntimeFilesGen):
    def __init__(self, project, sources):
        self.p = project
        self.sources = sources      # input file names, for comments
        self.lines = []
        self.ind = 0
        self.tmp = 0
        # the run-time rules of the build (stc/semantics.py): asked by name, never by semantics
        self.dialect = dialect("st", getattr(project, "semantics", "matiec"))

    # ---- output helpers
    def w(self, s=""):
        self.lines.append(("    " * self.ind + s) if s else "")

    @contextlib.contextmanager
    def braced(self, head):
        """head (a C function's signature), then what the with block writes in { }, one level in."""
        self.w(head)
        self.w("{")
        self.ind += 1
        yield
        self.ind -= 1
        self.w("}")

    def take(self):
        out = "\n".join(self.lines) + "\n"
        self.lines = []
        return out

    # ---- top level
    def generate(self, outdir):
        files = {}
        with open(os.path.join(os.path.dirname(os.path.dirname(__file__)), HEADER)) as f:
            files[HEADER] = f.read().replace(
                "#define STC_MATIEC 0", f"#define STC_MATIEC {1 if self.dialect.matiec_library else 0}", 1).replace(
                "#define STC_FORK 0", f"#define STC_FORK {1 if self.dialect.fork else 0}", 1)
        files["POUS.h"] = self.pous_h()
        files["POUS.c"] = self.pous_c()
        cfg_files = self.config_files()
        files.update(cfg_files)
        files["LOCATED_VARIABLES.h"] = self.located_h()
        files["SYMBOLS.tsv"] = self.symbols()
        files["RETAIN.c"] = self.retain_c()
        srcs = ["POUS.c", "Config0.c"] + sorted(k for k in cfg_files if k not in ("Config0.c",))
        srcs.append("RETAIN.c")
        files["SOURCES.txt"] = "\n".join(srcs) + "\n"
        os.makedirs(outdir, exist_ok=True)
        for name, text in files.items():
            path = os.path.join(outdir, name)
            try:
                with open(path) as f:
                    if f.read() == text:
                        continue
            except OSError:
                pass
            with open(path, "w") as f:
                f.write(text)
        return sorted(files)
