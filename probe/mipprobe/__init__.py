"""mip-probe: commissioning of a Piciorgros MIP radio network (docs/commissioning.md)."""
__version__ = "0.1.0"
