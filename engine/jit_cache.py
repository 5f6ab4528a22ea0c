"""numba's on-disk cache, keyed on every source file the engine's kernels are compiled from.

numba keys a cached kernel on its own file only: a kernel in tick.py that inlines bat_step from
bat.py keeps running the old bat_step after bat.py changes (numba's documented limitation,
numba issues #1833 and #9483, PR #8396 still open). This session met it: a fix to bat.py was
silently not in the tests that ran. So the cache lives in a directory named after a hash of the
engine's and the net kernel's sources: any change to either starts a fresh cache, which is
always right (and on a fresh checkout, as in CI, costs nothing more).

It must run before the first `@njit(cache=True)` of the engine is decorated: engine/__init__.py
calls it. NUMBA_CACHE_DIR set by the user wins.
"""
from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

KEEP = 3  # cache directories kept: the current one and the two before it (switching branches)


def sources_hash(packages: list[Path]) -> str:
    """sha256 over the names and bytes of every .py file in the packages, in a fixed order."""
    digest = hashlib.sha256()
    for package in packages:
        for path in sorted(package.glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def use_source_keyed_cache() -> Path | None:
    """Point numba's cache at .numba_cache/<hash of the sources>; returns it (None: left alone)."""
    import numba

    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    here = Path(__file__).resolve().parent
    root = here.parent / ".numba_cache"
    cache = root / sources_hash([here, here.parent / "net_kernel"])
    try:
        cache.mkdir(parents=True, exist_ok=True)
        os.utime(cache)  # newest first when pruning
    except OSError:
        return None  # a read-only install: numba's own choice
    numba.config.CACHE_DIR = str(cache)
    # Keep the directory for the children too (forkserver workers import the engine anew).
    os.environ["NUMBA_CACHE_DIR"] = str(cache)
    old = sorted((p for p in root.iterdir() if p.is_dir() and p != cache), key=lambda p: p.stat().st_mtime)
    for stale in old[: max(0, len(old) - (KEEP - 1))]:
        shutil.rmtree(stale, ignore_errors=True)
    return cache
