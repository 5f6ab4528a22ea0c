"""The table net: topology builder, numba spring kernels and their numpy twins."""
from net_kernel.jit_cache import use_source_keyed_cache

use_source_keyed_cache()  # before any kernel is decorated (net_kernel/jit_cache.py says why)

from net_kernel.kernels import NO_CONTACT, collide_ball, knot_speed_max, step_knots, step_knots_implicit, step_knots_serial  # noqa: E402
from net_kernel.bound import NetBoundError  # noqa: E402
from net_kernel.sim import BACKENDS, NetContact, NetSim  # noqa: E402
from net_kernel.topology import (  # noqa: E402
    IMPLICIT,
    NET_HEIGHT,
    NET_WIDTH,
    SEMI_IMPLICIT,
    NetSpec,
    NetTopology,
    build_topology,
    grid_spec,
    make_topology,
    stability_bound,
    validate_spec,
)

__all__ = [
    "BACKENDS",
    "IMPLICIT",
    "NET_HEIGHT",
    "NET_WIDTH",
    "NO_CONTACT",
    "NetBoundError",
    "NetContact",
    "NetSim",
    "NetSpec",
    "NetTopology",
    "SEMI_IMPLICIT",
    "build_topology",
    "collide_ball",
    "grid_spec",
    "knot_speed_max",
    "make_topology",
    "stability_bound",
    "step_knots",
    "step_knots_implicit",
    "step_knots_serial",
    "validate_spec",
]
