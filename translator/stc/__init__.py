"""stc: translate IEC 61131-3 Structured Text (matiec dialect) to C with the matiec runtime ABI."""

__version__ = "0.1.0"
