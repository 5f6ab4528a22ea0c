"""numba's cache is keyed on the engine's sources (engine/jit_cache.py)."""
import os
from pathlib import Path

import numba
import pytest

import engine.tick
from engine.jit_cache import sources_hash


def test_any_source_change_changes_the_key(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "x.py").write_text("X = 1\n")
    (b / "y.py").write_text("Y = 1\n")
    before = sources_hash([a, b])
    assert sources_hash([a, b]) == before  # deterministic
    (b / "y.py").write_text("Y = 2\n")  # a change in the second package, as bat.py for tick.py
    assert sources_hash([a, b]) != before
    (b / "y.py").write_text("Y = 1\n")
    assert sources_hash([a, b]) == before
    (a / "z.py").write_text("")  # a new file counts too
    assert sources_hash([a, b]) != before


def test_the_engine_kernels_cache_where_the_key_says():
    root = Path(engine.__file__).resolve().parent
    if Path(numba.config.CACHE_DIR).parent.name != ".numba_cache":
        pytest.skip(f"NUMBA_CACHE_DIR={os.environ.get('NUMBA_CACHE_DIR')} chosen by the user")
    key = sources_hash([root, root.parent / "net_kernel"])
    assert Path(numba.config.CACHE_DIR).name == key
    assert engine.tick.advance_ticks._cache._cache_path.startswith(numba.config.CACHE_DIR)
