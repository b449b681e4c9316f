"""mipkit: the test kit for integrators (docs/test-kit.md).

Your own ST programs as soft-PLCs (plcrt, built with stc or matiec) on an emulated TRM-810 /
MDP-810 radio network, with a note-following peer as the other side, in deterministic virtual
time: a pytest plugin (fixture ``mip_network``) and a scenario command (``mip-kit``)."""
from .base import KitError, KitWarning
from .net import Net, assert_records
from .ends import KitRelay, KitScada, KitUnicos, missing

__all__ = ["KitError", "KitWarning", "Net", "assert_records", "KitRelay", "KitScada", "KitUnicos",
           "missing"]


def _seqdiag_mod():
    """docs/tools/seqdiag.py, the diagram generator of the docs: installed as mipkit._seqdiag
    (kit/setup.py copies it), or from the checkout this package runs in."""
    try:
        from . import _seqdiag
        return _seqdiag
    except ImportError:
        import importlib.util
        from pathlib import Path
        path = Path(__file__).resolve().parents[2] / "docs" / "tools" / "seqdiag.py"
        spec = importlib.util.spec_from_file_location("mipkit_seqdiag", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
