"""The names of stc's run-time semantics and source dialects, and the rules each one decides:
the one place (stc, plcharness, the kit and their command lines take the names from here).

Run-time semantics (`stc --semantics`): "matiec" reproduces upstream matiec's run-time values
(the default), "openplc" OpenPLC v3's matiec fork, "iec" IEC 61131-3 where the two differ.
Source dialects (`stc --dialect`, or a file's name): "st" (the matiec dialect), "scl" (TIA
Portal SCL, scl_in.py), "twincat" / "codesys" (the vendors' ST, vendor_in.py).

`Dialect` holds every rule in which they differ, one named field a rule: the checker
(stc/check/) asks `self.dialect.<rule>` of the file it checks, the code generator (stc/cgen/)
`self.dialect.<rule>` of the build; neither tests a name. A new rule is a field here, set in
`dialect()`. Imports only the standard library, so that a caller need not load the translator
to name the semantics."""
from dataclasses import dataclass
from functools import lru_cache

SEMANTICS = ("matiec", "openplc", "iec")
SOURCE_DIALECTS = ("st", "scl", "twincat", "codesys")


@dataclass(frozen=True)
class Dialect:
    source: str                  # one of SOURCE_DIALECTS
    semantics: str               # one of SEMANTICS

    # ---- the source language (checker; False/None: the matiec dialect's rule)
    # (A := 0, B := 51, C) in a TYPE: an enumeration with those numbers (CODESYS / ModbusFB);
    # matiec rejects explicit values (design/matiec-dialect.md "Rejected"; reject/enum_explicit_values.st)
    enum_explicit_values: bool = False
    # Enum.Value for a value of an enumeration (CODESYS's qualified_only; TwinCAT accepts it);
    # matiec knows Enum#Value only
    enum_qualified_values: bool = False
    # TO_WORD(e) (any integer or bit type) of an enumerated value is its number (CODESYS);
    # matiec has no TO_* functions
    enum_to_number: bool = False
    # POINTER TO T, PVOID and p^ (TwinCAT 3 / CODESYS V3); matiec rejects pointers and
    # references (design/matiec-dialect.md "Rejected"; reject/pointer_to.st, ref_to.st)
    pointers: bool = False
    # ADR, SIZEOF, MEMCPY (Tc2_System), SysMemCpy (CODESYS SysMem): helpers.VENDOR_FUNCS
    address_functions: bool = False
    # STRING(n), n up to STRING's length, is a STRING (the IDEs' length syntax); matiec drops
    # or crashes on STRING[n] (design/matiec-dialect.md "Rejected"; reject/string_20.st)
    string_length_decl: bool = False
    # a VAR_IN_OUT of a function block type is a reference, bound in every call (CODESYS's
    # rClient); it crashes iec2c (design/matiec-dialect.md "Rejected"; reject/inout_fb_type.st)
    fb_in_out: bool = False
    # located variables (AT %I*) in a FUNCTION_BLOCK: one cell for every instance (TwinCAT
    # links an FB's AT %I* in its I/O mapping); matiec rejects them (reject/located_in_fb.st)
    located_in_fb: bool = False
    # arrays of the same bounds and element type assign and pass (the IDEs); matiec wants the
    # same named array TYPE on both sides (reject/array_anonymous_assign.st)
    arrays_by_shape: bool = False
    # every anonymous Array[a..b] of T is the named type ARRAY_a_b_OF_T, so arrays of one
    # shape are one type (TIA: our reading of the S7-1200/1500 manual; scl_in.name_arrays)
    arrays_named_by_shape: bool = False

    # ---- the run-time values (code generator; True: upstream matiec's value, measured
    # against iec2c by tests/translator/test_stc_matiec_values.py; False: IEC 61131-3's)
    # matiec's C and standard library (stc_rt.h STC_MATIEC): either matiec flavour
    matiec_library: bool = True
    # OpenPLC v3's fork of matiec (stc_rt.h STC_FORK)
    fork: bool = False
    # 8- and 16-bit integer arithmetic is computed in C int and truncated where it is stored
    # (matiec's C); IEC: in the type
    narrow_int_in_c_int: bool = True
    # TIME is a (tv_sec, tv_nsec) pair added, scaled, compared and converted as matiec's
    # library does (matiec_time.py, stc_rt.h stc_mt_*); IEC: int64 nanoseconds
    time_as_pair: bool = True
    # an untyped real literal is a C double, a typed function's REAL result a float (matiec's
    # C); IEC: REAL throughout
    real_as_c: bool = True
    # SHL / SHR take the count modulo 32 (64 for LWORD), as x86 C does under matiec; IEC: 0
    # beyond the width
    shift_count_modulo: bool = True
    # MUX with a selector outside 0..n-1 gives the type's initial value (matiec); IEC: the
    # last input
    mux_out_of_range_zero: bool = True
    # an FB's VAR_IN_OUT is copied in and out, the instance keeps its copy (matiec); IEC: a
    # reference
    fb_in_out_copy: bool = True
    # EN left out of an FB call keeps its last value (matiec); IEC: TRUE
    en_keeps_last: bool = True
    # FOR: no pass unless the first test holds, the increment before the next pass's test
    # (upstream matiec; the fork and IEC test before every pass)
    for_matiec_upstream: bool = False
    # the program instances run in declaration order, PRIORITY plays no part (matiec's
    # Config0.c); IEC: by PRIORITY
    tasks_in_declaration_order: bool = True


@lru_cache(maxsize=None)
def dialect(source="st", semantics="matiec"):
    """The rules of a source dialect under a run-time semantics (one shared object each)."""
    if source not in SOURCE_DIALECTS:
        raise ValueError(f"dialect must be one of {', '.join(SOURCE_DIALECTS)}, not {source!r}")
    if semantics not in SEMANTICS:
        raise ValueError(f"semantics must be one of {', '.join(SEMANTICS)}, not {semantics!r}")
    vendor = source in ("twincat", "codesys")
    matiec = semantics in ("matiec", "openplc")
    return Dialect(
        source=source, semantics=semantics,
        enum_explicit_values=vendor, enum_qualified_values=vendor, enum_to_number=vendor,
        pointers=vendor, address_functions=vendor, string_length_decl=vendor,
        fb_in_out=vendor, located_in_fb=vendor, arrays_by_shape=vendor,
        arrays_named_by_shape=source == "scl",
        matiec_library=matiec, fork=semantics == "openplc",
        narrow_int_in_c_int=matiec, time_as_pair=matiec, real_as_c=matiec,
        shift_count_modulo=matiec, mux_out_of_range_zero=matiec, fb_in_out_copy=matiec,
        en_keeps_last=matiec, for_matiec_upstream=semantics == "matiec",
        tasks_in_declaration_order=matiec)
