"""Fixtures the whole suite shares."""
import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


@pytest.fixture(autouse=True, scope="session")
def scene_cache(tmp_path_factory):
    """Served scenes a client of the suite is sent are kept in a folder of the run's own, never
    the user's cache (processes.network.client.scenes; child processes inherit it)."""
    import os

    from processes.network.client.scenes import CACHE_ENV

    folder = tmp_path_factory.mktemp("scene_cache")
    before = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(folder)
    yield folder
    if before is None:
        os.environ.pop(CACHE_ENV, None)
    else:
        os.environ[CACHE_ENV] = before
