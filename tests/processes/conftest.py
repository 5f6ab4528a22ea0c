"""Process tests: every wait bounded, every process and segment cleaned up even on failure."""
import multiprocessing

import pytest

from processes import shm


@pytest.fixture
def ctx():
    return multiprocessing.get_context("forkserver")


@pytest.fixture
def no_leftovers():
    """Fails the test if a run it started leaves a segment in /dev/shm (other runs on the
    machine, a concurrent CI for one, are not its business)."""
    before = set(shm.created_run_ids)
    yield
    left = [name for run_id in shm.created_run_ids - before for name in shm.leftover_segments(run_id)]
    assert not left, f"segments left behind: {sorted(left)}"


@pytest.fixture
def procs():
    """Processes a test starts; all are killed and joined at the end, whatever happened."""
    started = []
    yield started
    for p in started:
        if p.is_alive():
            p.kill()
        p.join(5)
