"""Process tests: every wait bounded, every process and segment cleaned up even on failure."""
import multiprocessing

import pytest

from processes.shm import leftover_segments


@pytest.fixture
def ctx():
    return multiprocessing.get_context("forkserver")


@pytest.fixture
def no_leftovers():
    """Fails the test if it leaves a segment of this project in /dev/shm."""
    before = set(leftover_segments())
    yield
    left = set(leftover_segments()) - before
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
