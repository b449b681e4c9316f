"""The build cache: a build's key (its sources, the runtime's, the translator's), where the
cache is, pruning it, and the runtime's own objects compiled once per compiler and flags."""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from pathlib import Path

from .build_common import (BUILD_FORMAT, CORE_SOURCES, HERE, REPO_ROOT, RUNTIME_DIR, BuildError,
                           _compile)
from .matiec import matiec_paths

# the modules whose code decides what a build produces: part of every key
BUILD_MODULES = ("build.py", "build_common.py", "build_cache.py", "matiec.py")


def _hash_inputs(sources, compiler, extra):
    h = hashlib.sha256()
    h.update(BUILD_FORMAT.encode())
    h.update(compiler.encode())
    h.update(extra.encode())
    for src in sources:
        h.update(Path(src).name.encode())
        h.update(Path(src).read_bytes())
    for f in sorted((RUNTIME_DIR / "src").glob("*")) + sorted((RUNTIME_DIR / "include").glob("*")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    for name in BUILD_MODULES:
        h.update((HERE / name).read_bytes())
    return h.hexdigest()[:24]


def _compiler_fingerprint(compiler):
    if compiler == "matiec":
        iec2c, lib = matiec_paths()
        if not iec2c:
            raise BuildError("matiec: iec2c not found on PATH (or env IEC2C)")
        st = os.stat(iec2c)
        # stc too: it supplies the arrays and structs of a matiec build
        return (f"{iec2c}:{st.st_size}:{st.st_mtime_ns}:{lib}:{os.environ.get('MATIEC_FLAGS', '')}"
                f":{_compiler_fingerprint('stc')}")
    # stc: its own sources decide what it produces
    h = hashlib.sha256()
    if REPO_ROOT is not None:
        stc_dir = REPO_ROOT / "translator" / "stc"
    else:
        import importlib.util
        spec = importlib.util.find_spec("stc")
        stc_dir = Path(spec.origin).parent if spec and spec.origin else Path("/nonexistent")
    for f in sorted(stc_dir.rglob("*")) if stc_dir.is_dir() else []:
        if f.is_file() and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(stc_dir)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _cache_root():
    env = os.environ.get("PLCRT_CACHE")
    if env == "off":
        return None
    if env:
        root = Path(env)
    elif REPO_ROOT is not None:
        root = REPO_ROOT / "build" / "runtime_shim" / "cache"
    else:   # installed: the user's cache directory
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "plcrt"
    try:
        root.mkdir(parents=True, exist_ok=True)
        return root
    except OSError:
        return None


CACHE_KEEP = 400  # entries (about 1 MB each); the oldest go first
CORE_DIR = "core-objects"  # in the cache: the runtime's own objects, see _core_objects
CORE_KEEP = 4              # sets of them (compiler and flags); the oldest go first


def _prune_cache(cache: Path, keep=CACHE_KEEP):
    """The entries of cache beyond the newest keep go (not CORE_DIR, not builds under way)."""
    try:
        entries = [e for e in cache.iterdir() if e.is_dir() and e.name != CORE_DIR
                   and not e.name.startswith("plcrt-build-")]
        if len(entries) <= keep:
            return
        entries.sort(key=lambda e: e.stat().st_mtime)
        for e in entries[:len(entries) - keep]:
            shutil.rmtree(e, ignore_errors=True)
    except OSError:
        pass  # another process pruned at the same time


def _core_objects(cache, cc, cflags, mb_cflags, out: Path):
    """The objects of the runtime's own sources (CORE_SOURCES and plcrt_main.c): the same for
    every program, so with a cache they are compiled once per compiler, flags and runtime
    sources instead of in every build (about 3 s of a small program's 6). Returns
    (the core objects, plcrt_main.o). Without a cache they are compiled into out."""
    names = CORE_SOURCES + ["plcrt_main.c"]
    src = RUNTIME_DIR / "src"

    def compile_into(d: Path):
        for name in names:
            flags = [*cflags, *mb_cflags] if name != "plcrt_main.c" else cflags
            _compile([cc, *flags, "-c", str(src / name), "-o", str(d / (Path(name).stem + ".o"))],
                     f"compiling {name}")

    def result(d: Path):
        objs = [d / (Path(n).stem + ".o") for n in names]
        return objs[:-1], objs[-1]

    if cache is None:
        compile_into(out)
        return result(out)
    h = hashlib.sha256()
    cc_path = shutil.which(cc)
    st = os.stat(cc_path) if cc_path else None
    h.update(f"{cc}:{cc_path}:{st.st_size if st else 0}:{st.st_mtime_ns if st else 0}".encode())
    h.update(repr(cflags).encode())
    h.update(repr(mb_cflags).encode())
    for f in sorted(src.glob("*")) + sorted((RUNTIME_DIR / "include").glob("*")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    root = cache / CORE_DIR
    d = root / h.hexdigest()[:24]
    core, main = result(d)
    if all(o.is_file() for o in core + [main]):
        try:
            os.utime(d)  # recently used: pruned last
        except OSError:
            pass
        return core, main
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="plcrt-build-", dir=root))
    try:
        compile_into(tmp)
        try:
            os.rename(tmp, d)  # atomic; a concurrent build may have won: then use its objects
            tmp = None
        except OSError:
            pass
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    try:
        os.utime(d)  # this build's set stays, also when a concurrent build's rename won
    except OSError:
        pass
    _prune_cache(root, CORE_KEEP)
    return core, main

