"""Fixtures of the net kernel's tests: a small net."""
import pytest

from net_kernel.topology import build_topology, grid_spec


@pytest.fixture
def small_topo():
    """A 24 x 8 net of the default cloth (fast to compile against and to step)."""
    return build_topology(grid_spec(24, 8))
