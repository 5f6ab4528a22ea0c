"""Numba kernels of the net: knot steps (semi-implicit and implicit Euler) and the ball's contact.

One module per layout or concern: csr (knot steps over the CSR adjacency, any topology), grid
(the same step on a regular grid, in flat loops over it), grid32 (the grid step in float32 on offsets
from the built grid, a NetSpec option), implicit (backward Euler by conjugate gradients),
contact (the ball against the knots, and a grid net's whole tick with the ball near), modal
(the linear tail in closed form: the motion's energy, modal coordinates, the state at a tick,
the sleep bound), scatter (the textbook per-spring scatter loop, a baseline for the profile,
not used by NetSim). Numba only; the numpy twins are in
net_kernel/reference.py.

Model (issue 4, after Provot, "Deformation constraints in a mass-spring model", Graphics
Interface 1995): each spring s between knots i and j is a spring-damper; with
L = x_j - x_i, n = L/|L|, the force on knot i is

    f_i = (k_s (|L| - L_rest) + k_d ((v_j - v_i) . n)) n,      f_j = -f_i.

Determinism: every sum over springs here is a per-knot gather in a fixed order: over the CSR
adjacency (knot i sums its own springs in the topology's slot order), or, in the grid kernels
(step_grid), over the 8 grid neighbours in that same order; per-spring passes write one value
per spring. So `parallel=True` changes no bit: no prange scatter-add, no prange reduction;
reductions (CG dot products, speed maximum) are serial loops. fastmath stays off, except the
grid32 FMA variant's flag contract, which reorders no sum (see grid32). No kernel
allocates; scratch comes in as arguments.

error_model="numpy" on the step kernels: no ZeroDivisionError test on 1/|L| (the builder
refuses zero-length springs, and a collapse would surface as a non-finite knot, which NetSim
checks after every tick). With python's error model that test keeps the root/division loops
scalar.

Knot-table contact (table): after every step a free knot below the playing surface is put back
on it with its downward velocity removed.

Every kernel has a numpy twin with the same signature in net_kernel/reference.py.
"""
from net_kernel.kernels.contact import (
    NEAR_SLACK,
    NO_CONTACT,
    TICK_BALL_ROWS,
    collide_ball,
    collide_ball_near,
    step_grid32_ball,
    step_grid32_tick,
    step_grid_ball,
    step_grid_tick,
)
from net_kernel.kernels.csr import STEP_WORK_ROWS, knot_speed_max, step_knots, step_knots_serial
from net_kernel.kernels.grid import (
    FREE_ASLEEP,
    FREE_AWAKE,
    FREE_NOT_FINITE,
    FREE_OUT_OF_REACH,
    GRID_CLASSES,
    GRID_CORD,
    GRID_HEM,
    GRID_MESH,
    GRID_SHEAR,
    GRID_VERTICAL,
    GRID_WORK_LINES,
    grid_knots,
    grid_work,
    step_grid,
    step_grid_free,
    step_grid_serial,
)
from net_kernel.kernels.grid32 import (
    GRID32_EXACT,
    GRID32_FMA,
    grid32_work,
    step_grid32,
    step_grid32_free,
    step_grid32_serial,
)
from net_kernel.kernels.implicit import KNOT_WORK_ROWS, SPRING_WORK_COLS, step_knots_implicit
from net_kernel.kernels.modal import (
    FREE_TAIL,
    modal_bounds,
    modal_coefficients,
    modal_detuning,
    modal_state,
    motion_energy,
    potential_energy,
    quiet_from,
    step_grid32_free_tail,
    step_grid_free_tail,
)
from net_kernel.kernels.scatter import step_knots_scatter
from net_kernel.kernels.table import TABLE_Z

__all__ = [
    "FREE_ASLEEP",
    "FREE_AWAKE",
    "FREE_NOT_FINITE",
    "FREE_OUT_OF_REACH",
    "FREE_TAIL",
    "GRID32_EXACT",
    "GRID32_FMA",
    "GRID_CLASSES",
    "GRID_CORD",
    "GRID_HEM",
    "GRID_MESH",
    "GRID_SHEAR",
    "GRID_VERTICAL",
    "GRID_WORK_LINES",
    "KNOT_WORK_ROWS",
    "NEAR_SLACK",
    "NO_CONTACT",
    "SPRING_WORK_COLS",
    "STEP_WORK_ROWS",
    "TABLE_Z",
    "TICK_BALL_ROWS",
    "collide_ball",
    "collide_ball_near",
    "grid32_work",
    "grid_knots",
    "grid_work",
    "knot_speed_max",
    "modal_bounds",
    "modal_coefficients",
    "modal_detuning",
    "modal_state",
    "motion_energy",
    "potential_energy",
    "quiet_from",
    "step_grid",
    "step_grid32",
    "step_grid32_ball",
    "step_grid32_free",
    "step_grid32_serial",
    "step_grid32_tick",
    "step_grid_ball",
    "step_grid_free",
    "step_grid32_free_tail",
    "step_grid_free_tail",
    "step_grid_serial",
    "step_grid_tick",
    "step_knots",
    "step_knots_implicit",
    "step_knots_scatter",
    "step_knots_serial",
]
