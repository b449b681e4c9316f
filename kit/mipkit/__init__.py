"""mipkit: the test kit for integrators (docs/test-kit.md).

Your own ST programs as soft-PLCs (plcrt, built with stc or matiec) on an emulated TRM-810 /
MDP-810 radio network, with a note-following peer as the other side, in deterministic virtual
time: a pytest plugin (fixture ``mip_network``) and a scenario command (``mip-kit``)."""
from .base import KitError, KitWarning
from .net import Net, assert_records
from .ends import KitRelay, KitScada, KitUnicos, missing

__all__ = ["KitError", "KitWarning", "Net", "assert_records", "KitRelay", "KitScada", "KitUnicos",
           "missing"]

