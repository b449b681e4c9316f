"""Front end driver: parse every file, then check them together."""
from . import parser
from . import syntax as S
from .check import Checker


def compile_files(texts, diags):
    """texts: [(filename, text, is_library)]. Returns a Project (valid only without errors)."""
    parsed = []
    for fname, text, lib in texts:
        nodes = parser.parse(text, fname, diags)
        if nodes is None:
            continue
        if lib:
            nodes = [n for n in nodes if not isinstance(n, S.Configuration)]
        parsed.append((fname, nodes))
    if diags:
        return None
    return Checker(diags).run(parsed)
