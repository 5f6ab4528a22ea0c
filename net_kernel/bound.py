"""Where a ringing net's knots can be while nothing touches it: a box from its energy."""
from __future__ import annotations

import numpy as np

from net_kernel.kernels.modal import potential_energy
from net_kernel.modes import NetModes
from net_kernel.topology import NetTopology

# In the linear model no knot is farther from the rest shape, along an axis, than
# sqrt(2 E compliance) while the net's energy above rest is at most E (NetModes.compliance: by
# Cauchy-Schwarz over the mass-normalised modes, u_i^2 <= (sum_m phi_im^2 / w_m^2) (sum_m w_m^2 q_m^2)
# <= compliance * 2 E), and the energy only falls while nothing touches the net (its dashpots and
# the air take it away). The energy is taken this many times over: the scheme's own energy is
# not exactly monotone from substep to substep, and the linear model is the hanging net's (its
# threads stiffen as they stretch, which keeps a knot nearer for the same energy).
BOUND_ENERGY_FACTOR = 2.0


class NetBoundError(RuntimeError):
    """A knot left the box knot_bound gave: a caller may have stepped a tick without the ball
    that the ball could have touched."""


def knot_bound(topo: NetTopology, modes: NetModes, knot_pos: np.ndarray, knot_vel: np.ndarray, rest_box: np.ndarray,
               reach: np.ndarray) -> np.ndarray:
    """(2, 3) m: lo and hi corners of a box that holds every knot of the net in state knot_pos,
    knot_vel ((n_knots, 3) m, m/s) from now on while nothing touches it, within `reach` (the
    (2, 3) box no knot leaves); rest_box: (2, 3) m, the box of modes.rest_pos."""
    kinetic = 0.5 * float(np.einsum("i,ij,ij->", topo.knot_mass, knot_vel, knot_vel))
    energy = kinetic + float(potential_energy(knot_pos, topo.knot_mass, topo.knot_inv_mass, topo.spring_ij,
                                              topo.spring_rest, topo.spring_k, topo.spec.gravity)) - modes.rest_energy
    span = np.sqrt(2.0 * BOUND_ENERGY_FACTOR * max(energy, 0.0) * modes.compliance)
    return np.array([np.maximum(rest_box[0] - span, reach[0]), np.minimum(rest_box[1] + span, reach[1])])


def out_of_bound(bound: np.ndarray, box: np.ndarray) -> str:
    """The message of a NetBoundError: the bound and the knots' box (both (2, 3) m)."""
    return (f"a knot of the net left the box its energy bounds it to ({bound.tolist()} m; knots now span "
            f"{box.tolist()} m): BOUND_ENERGY_FACTOR = {BOUND_ENERGY_FACTOR} is too small for this net")
