"""The linear tail of a struck net's ring: its state held as modal coordinates, in closed form.

A LinearTail starts from one knot state (the switch) and from then on is a function of the
ticks since the switch alone: tail_state(n) evaluates net_kernel.kernels.modal.modal_state at
n, whatever happened in between (one jump of a thousand ticks or a thousand single ticks, a
process restarted from the switch state and n). Nothing is stepped while the tail holds the net.

It knows from the start, by bounds on its modes, a box that holds every knot from then on
(the ball is far from the net when it is far from that box) and the tick from which no knot
can be as fast as NetSim's SLEEP_SPEED again: the net falls asleep SLEEP_TICKS - 1 ticks
after it, as NetSim's rule asks (every knot slower than SLEEP_SPEED for SLEEP_TICKS ticks).
The bounds are sums of the modes' amplitudes, so the tail sleeps no earlier than stepping its
modes tick by tick would, and later by their margin; a tail's tick costs nothing either way.
"""
from __future__ import annotations

import numpy as np

from net_kernel import kernels as numba_kernels
from net_kernel.kernels.table import TABLE_Z
from net_kernel.modes import NetModes

# Ticks a tail may last before it is taken to sleep regardless: 10^7 ticks (hours of a 1 ms
# tick). Every mode decays, so the bound falls below any speed long before.
MAX_TAIL_TICKS = 10_000_000


class LinearTail:
    """The ring of one net in closed form from one switch state on (see the module's docstring).

    Args:
        modes: the net's NetModes (net_kernel.modes.net_modes).
        backend: the module of kernels it evaluates with (net_kernel.kernels or net_kernel.reference).

    Attributes:
        ticks: ticks since the switch.
        sleep_at: the tick (since the switch) at which the net falls asleep.
        quiet_ticks: NetSim's quiet-tick count at the switch; sleep_quiet: the count at sleep_at.
        box: (2, 3) m, lo and hi corners of a box that holds every knot from the switch on.
        start_pos, start_vel: (n_knots, 3) m, m/s, the switch state.
    """

    def __init__(self, modes: NetModes, backend=numba_kernels):
        self.modes = modes
        self._kernels = backend
        n_out, k2 = modes.out_e.size, modes.in_log_r.size
        n_knots, n_free = modes.rest_pos.shape[0], modes.free.size
        self._out_c = np.zeros(n_out, dtype=np.complex128)
        self._out_shift = np.zeros(n_out)
        self._in_w = np.zeros(k2, dtype=np.complex128)
        self._in_scratch = np.zeros(k2)
        self._q, self._p = np.zeros(n_out), np.zeros(n_out)
        self._xi = np.zeros((2, k2))
        self._dofs = np.zeros((4, 2 * n_free))
        self._disp, self._speed = np.zeros((3, n_free)), np.zeros((3, n_free))
        self.start_pos, self.start_vel = np.zeros((n_knots, 3)), np.zeros((n_knots, 3))
        self.box = np.zeros((2, 3))
        self.ticks = 0
        self.sleep_at = 0
        self.sleep_quiet = 0
        self.quiet_ticks = 0

    def start(self, knot_pos: np.ndarray, knot_vel: np.ndarray, quiet_ticks: int, sleep_speed: float,
              sleep_ticks: int) -> bool:
        """Take the net over from this state (ticks = 0). Returns False, and holds nothing, when
        the bounds let a free knot reach the playing surface (its contact is not linear)."""
        m = self.modes
        self.start_pos[:] = knot_pos
        self.start_vel[:] = knot_vel
        k = self._kernels
        k.modal_coefficients(self.start_pos, self.start_vel, m.rest_pos, m.free, m.out_proj, m.out_e, m.in_proj,
                             m.in_inverse, self._out_c, self._in_w, self._q, self._p, self._in_scratch, self._dofs)
        k.modal_detuning(m.out_detune, self._out_c, self._out_shift)
        k.modal_bounds(m.out_shape, self._out_c, m.out_e, self._out_shift, m.out_rate, m.in_pos_abs, m.in_vel_abs,
                       self._in_w, self._disp, self._speed)
        rest = m.rest_pos[m.free]
        disp = self._disp.T
        if float((rest[:, 2] - disp[:, 2]).min()) <= TABLE_Z:
            return False
        np.minimum((rest - disp).min(axis=0), m.rest_pos.min(axis=0), out=self.box[0])
        np.maximum((rest + disp).max(axis=0), m.rest_pos.max(axis=0), out=self.box[1])
        quiet = k.quiet_from(sleep_speed, MAX_TAIL_TICKS, m.out_log_r, m.in_log_r, self._speed)
        if quiet == 1:  # quiet from the first tick on: the count goes on from the switch's
            self.sleep_at = max(1, sleep_ticks - quiet_ticks)
            self.sleep_quiet = quiet_ticks + self.sleep_at
        else:  # quiet from tick `quiet` on, perhaps not before
            self.sleep_at = quiet + sleep_ticks - 1
            self.sleep_quiet = sleep_ticks
        self.quiet_ticks = int(quiet_ticks)
        self.ticks = 0
        return True

    def state(self, ticks: int, knot_pos: np.ndarray, knot_vel: np.ndarray) -> None:
        """The tail's knot state `ticks` ticks after the switch, into knot_pos and knot_vel ((n_knots, 3) views)."""
        m = self.modes
        self._kernels.modal_state(int(ticks), m.rest_pos, m.free, m.out_shape, self._out_c, m.out_e, m.out_log_r, m.out_theta,
                                  self._out_shift, m.out_rate, m.in_pos, m.in_vel, self._in_w, m.in_log_r, m.in_theta, self._q, self._p, self._xi,
                                  self._dofs, knot_pos, knot_vel)
