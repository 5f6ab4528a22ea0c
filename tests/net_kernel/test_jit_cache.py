"""numba's cache is keyed on every source of net_kernel/ and engine/, subpackages included (net_kernel/jit_cache.py)."""
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
import pytest

import engine.physics.tick
import net_kernel
import net_kernel.jit_cache
from net_kernel.jit_cache import keyed_packages, sources_hash
from net_kernel.kernels import step_grid
from tests.waits import DEADLINE_S


def test_any_source_change_changes_the_key(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    (a / "sub").mkdir(parents=True)
    b.mkdir()
    (a / "x.py").write_text("X = 1\n")
    (a / "sub" / "y.py").write_text("Y = 1\n")
    (b / "z.py").write_text("Z = 1\n")
    before = sources_hash([a, b])
    assert sources_hash([a, b]) == before  # deterministic
    (a / "sub" / "y.py").write_text("Y = 2\n")  # a change in a subpackage
    assert sources_hash([a, b]) != before
    (a / "sub" / "y.py").write_text("Y = 1\n")
    assert sources_hash([a, b]) == before
    (b / "z.py").write_text("Z = 2\n")  # a change in the second package, as the engine's for the net kernels
    assert sources_hash([a, b]) != before
    (b / "z.py").write_text("Z = 1\n")
    (a / "sub" / "y.py").rename(a / "y.py")  # the same bytes under another path
    assert sources_hash([a, b]) != before
    (a / "y.py").rename(a / "sub" / "y.py")
    (a / "sub" / "new.py").write_text("")  # a new file counts too
    assert sources_hash([a, b]) != before


def test_the_kernels_cache_where_the_key_says():
    if Path(numba.config.CACHE_DIR).parent.name != ".numba_cache":
        pytest.skip(f"NUMBA_CACHE_DIR={os.environ.get('NUMBA_CACHE_DIR')} chosen by the user")
    root = Path(net_kernel.__file__).resolve().parent.parent
    assert Path(numba.config.CACHE_DIR).name == sources_hash(keyed_packages(root))
    assert os.environ["NUMBA_CACHE_DIR"] == numba.config.CACHE_DIR  # what child processes inherit
    for kernel in (step_grid, engine.physics.tick.advance_ticks):  # a net kernel in a subpackage, an engine kernel
        assert kernel._cache._cache_path.startswith(numba.config.CACHE_DIR)  # noqa: SLF001


# A stand-in for the two packages: net_kernel/kernels/kernel.py's cached kernel inlines a helper
# from net_kernel/kernels/helper.py, as the grid and contact kernels call each other's.
_HELPER = "from numba import njit\n\n\n@njit(cache=True)\ndef scale(x):\n    return {factor} * x\n"
_KERNEL = textwrap.dedent("""\
    from numba import njit

    from net_kernel.kernels.helper import scale


    @njit(cache=True)
    def twice(x):
        return scale(x)
    """)
_INIT = textwrap.dedent("""\
    from net_kernel.jit_cache import use_source_keyed_cache

    use_source_keyed_cache()
    """)
# Prints the kernel's result, the cache directory, this file's package, and the cache directory a
# forkserver child (which imports the packages anew) sees.
_RUN = textwrap.dedent(f"""\
    import multiprocessing
    import numba
    import net_kernel
    from net_kernel.kernels.kernel import twice
    import probe

    if __name__ == "__main__":
        with multiprocessing.get_context("forkserver").Pool(1) as pool:
            child = pool.apply_async(probe.cache_dir).get(timeout={DEADLINE_S})
        print(twice(2.0), numba.config.CACHE_DIR, net_kernel.__file__, child)
    """)
_PROBE = "import numba\nimport net_kernel  # noqa: F401\n\n\ndef cache_dir():\n    return numba.config.CACHE_DIR\n"


def _tree(root: Path) -> None:
    kernels = root / "net_kernel" / "kernels"
    kernels.mkdir(parents=True)
    (root / "engine").mkdir()
    (root / "engine" / "__init__.py").write_text("")
    shutil.copy(net_kernel.jit_cache.__file__, root / "net_kernel" / "jit_cache.py")
    (root / "net_kernel" / "__init__.py").write_text(_INIT)
    (kernels / "__init__.py").write_text("")
    _set_helper(root, 2.0)
    (kernels / "kernel.py").write_text(_KERNEL)
    (root / "probe.py").write_text(_PROBE)
    (root / "run.py").write_text(_RUN)


def _set_helper(root: Path, factor: float) -> None:
    """Rewrite only helper.py: numba sees kernel.py's own file unchanged."""
    (root / "net_kernel" / "kernels" / "helper.py").write_text(_HELPER.format(factor=factor))


def _run(root: Path, cache_dir: Path | None) -> tuple[float, Path]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env["PYTHONPATH"] = str(root)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    out = subprocess.run([sys.executable, "run.py"], cwd=root, env=env, capture_output=True, text=True,
                         timeout=DEADLINE_S, check=True)
    value, cache, package, child = out.stdout.split()
    assert Path(package).resolve().is_relative_to(root.resolve())  # the stand-in, not the installed net_kernel
    assert child == cache  # a forkserver child uses its parent's cache directory
    return float(value), Path(cache)


def test_a_changed_kernel_in_a_subpackage_is_recompiled(tmp_path):
    _tree(tmp_path)
    value, cache = _run(tmp_path, None)
    assert value == 4.0
    assert cache.parent == tmp_path / ".numba_cache"
    assert any(cache.rglob("*.nbi"))  # the kernel was cached there, so a stale one could have been loaded
    _set_helper(tmp_path, 3.0)  # the helper changes, the kernel's own file does not
    value, changed = _run(tmp_path, None)
    assert value == 6.0  # the new helper: compiled afresh in a new directory
    assert changed.parent == cache.parent and changed != cache


def test_numba_alone_keeps_the_stale_kernel_and_the_users_cache_dir_wins(tmp_path):
    # The control: in one fixed directory (NUMBA_CACHE_DIR set by the user, so used as it is),
    # numba serves the kernel compiled with the old helper (numba issues #1833, #9483). If this
    # starts failing, numba keys on the inlined files itself and net_kernel/jit_cache.py may go.
    fixed = tmp_path / "fixed"
    _tree(tmp_path)
    value, cache = _run(tmp_path, fixed)
    assert (value, cache) == (4.0, fixed)
    _set_helper(tmp_path, 3.0)
    value, cache = _run(tmp_path, fixed)
    assert (value, cache) == (4.0, fixed)  # stale, as the numba issues describe
    assert not (tmp_path / ".numba_cache").exists()
