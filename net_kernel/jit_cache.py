"""numba's on-disk cache, in a directory keyed on every source file the kernels are compiled from.

numba keys a cached kernel on its own file only: a kernel that inlines or calls a function
from another file keeps running the old compiled code after that other file changes (numba's
documented limitation, numba issues #1833 and #9483; PR #8396 still open). The engine's
kernels inline the net kernels', and the net kernels call each other across the modules of
net_kernel/kernels/. So the cache lives in .numba_cache/<hash>, where the hash covers the
names and bytes of every .py file under net_kernel/ and engine/, subpackages included: any
change to either starts a fresh cache, which is always right (and on a fresh checkout, as in
CI, costs nothing more). engine/ is read as bytes from beside net_kernel/, not imported, so
net_kernel still imports only numpy and numba.

It must run before the first `@njit(cache=True)` is decorated: net_kernel/__init__.py calls
it, and the engine imports net_kernel first. NUMBA_CACHE_DIR set by the user wins; the
directory chosen here is exported as NUMBA_CACHE_DIR, so child processes (forkserver workers
import the packages anew) use the same one.
"""
from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

KEEP = 3  # cache directories kept: the current one and the two before it (switching branches)
KEYED_PACKAGES = ("net_kernel", "engine")  # folders beside this package whose sources key the cache


def sources_hash(packages: list[Path]) -> str:
    """sha256 over the relative paths and bytes of every .py file under the packages (recursive), in a fixed order.

    A package folder that does not exist counts as empty (an installation without the engine).
    """
    digest = hashlib.sha256()
    for package in packages:
        digest.update(package.name.encode() + b"\0")
        for path in sorted(package.rglob("*.py")):
            digest.update(path.relative_to(package).as_posix().encode() + b"\0")
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def keyed_packages(root: Path) -> list[Path]:
    """The package folders under the repository root `root` whose sources key the cache."""
    return [root / name for name in KEYED_PACKAGES]


def use_source_keyed_cache() -> Path | None:
    """Point numba's cache at .numba_cache/<hash of the sources>; returns it (None: left alone)."""
    import numba

    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    root = Path(__file__).resolve().parent.parent
    cache_root = root / ".numba_cache"
    cache = cache_root / sources_hash(keyed_packages(root))
    try:
        cache.mkdir(parents=True, exist_ok=True)
        os.utime(cache)  # newest first when pruning
    except OSError:
        return None  # a read-only install: numba's own choice
    numba.config.CACHE_DIR = str(cache)
    os.environ["NUMBA_CACHE_DIR"] = str(cache)
    old = sorted((p for p in cache_root.iterdir() if p.is_dir() and p != cache), key=lambda p: p.stat().st_mtime)
    for stale in old[: max(0, len(old) - (KEEP - 1))]:
        shutil.rmtree(stale, ignore_errors=True)
    return cache
