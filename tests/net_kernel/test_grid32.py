"""The float32 grid kernels (kernels.grid32): their numpy twin, float64, blocks and threads, NetSim, accuracy."""
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.scene import SceneError, parse_scene
from net_kernel import kernels, reference
from net_kernel.sim import NetSim
from net_kernel.topology import NetSpec, build_topology, resolution_spec, validate_spec

EPS32 = float(np.finfo(np.float32).eps)
STEPS = 50
BALL_MASS = 2.7e-3  # kg, ITTF 2.3
BUDGET = 50e-6  # m, the error budget: a tenth of a knot's radius (KNOT_RADIUS 0.5 mm)


def _case(cols=23, rows=5, seed=0):
    """A grid net (the default cloth on cols x rows knots) in a perturbed, moving state."""
    topo = build_topology(NetSpec(cols=cols, rows=rows, knot_mass=0.05 / (cols * rows)))
    rng = np.random.default_rng(seed)
    free = (topo.knot_inv_mass > 0)[:, None]
    pos = topo.rest_pos + free * rng.normal(0.0, 1e-4, topo.knot_pos.shape)
    vel = free * rng.normal(0.0, 1e-2, topo.knot_pos.shape)
    state = np.zeros((2, 3, rows, cols))
    state[0] = pos.T.reshape(3, rows, cols)
    state[1] = vel.T.reshape(3, rows, cols)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    built = topo.knot_pos.T.reshape(3, rows, cols).copy()
    return topo, state, inv_mass, built, 0.9 * topo.h_max


def _tolerances(topo, h, steps):
    """(m, m/s): float32 rounding of `steps` steps, 8 rounded operations each (eps32 a step per
    operation), on a spring vector of the column spacing (positions) and on the largest spring
    tension, the top cord's, turned into a velocity by h / knot_mass (velocities)."""
    spacing = topo.spec.width / (topo.spec.cols - 1)
    tension = max(topo.spec.cord_tension, topo.spec.hem_tension, topo.spec.mesh_tension)
    per_step = 8 * EPS32
    return steps * per_step * spacing, steps * per_step * tension * h * float(topo.knot_inv_mass.max())


@pytest.mark.parametrize("variant", [kernels.GRID32_EXACT, kernels.GRID32_FMA])
def test_float32_kernel_against_its_numpy_twin(variant):
    topo, state, inv_mass, built, h = _case()
    fast, slow = state.copy(), state.copy()
    net32 = kernels.grid32_work(built, inv_mass, 1, variant)
    twin = reference.grid32_work(built, inv_mass, 1, variant)
    for a, b in zip(net32, twin):
        np.testing.assert_array_equal(a, b)  # the same constants and scratch
    kernels.step_grid32_serial(fast, inv_mass, topo.grid_params, 9.81, 5.0, h, STEPS, net32)
    reference.step_grid32(slow, inv_mass, topo.grid_params, 9.81, 5.0, h, STEPS, twin)
    if variant == kernels.GRID32_EXACT:
        np.testing.assert_array_equal(fast, slow)  # IEEE float32, the same operations in the same order
    else:
        x_tol, v_tol = _tolerances(topo, h, STEPS)
        np.testing.assert_allclose(fast[0], slow[0], rtol=0, atol=x_tol)  # fused products: float32 rounding apart
        np.testing.assert_allclose(fast[1], slow[1], rtol=0, atol=v_tol)


def test_float32_kernel_against_float64():
    topo, state, inv_mass, built, h = _case(seed=1)
    f64, f32 = state.copy(), state.copy()
    kernels.step_grid_serial(f64, inv_mass, topo.grid_params, 9.81, 5.0, h, STEPS,
                             kernels.grid_work(topo.spec.rows, topo.spec.cols))
    kernels.step_grid32_serial(f32, inv_mass, topo.grid_params, 9.81, 5.0, h, STEPS,
                               kernels.grid32_work(built, inv_mass, 1, kernels.GRID32_EXACT))
    x_tol, v_tol = _tolerances(topo, h, STEPS)
    np.testing.assert_allclose(f32[0], f64[0], rtol=0, atol=x_tol)  # float32 rounding of STEPS steps
    np.testing.assert_allclose(f32[1], f64[1], rtol=0, atol=v_tol)
    fixed = inv_mass == 0.0
    np.testing.assert_array_equal(f32[:, :, fixed], state[:, :, fixed])  # fixed knots keep their bits


@pytest.mark.parametrize("variant", [kernels.GRID32_EXACT, kernels.GRID32_FMA])
def test_float32_bits_do_not_depend_on_blocks_or_threads(variant):
    topo, state, inv_mass, built, h = _case(seed=2)
    runs = []
    for step, blocks in ((kernels.step_grid32_serial, 1), (kernels.step_grid32_serial, 3), (kernels.step_grid32, 3),
                         (kernels.step_grid32, 5)):
        s = state.copy()
        step(s, inv_mass, topo.grid_params, 9.81, 5.0, h, STEPS, kernels.grid32_work(built, inv_mass, blocks, variant))
        runs.append(s)
    for s in runs[1:]:
        np.testing.assert_array_equal(s, runs[0])


def test_no_float32_step_leaves_the_state_as_it_was():
    topo, state, inv_mass, built, h = _case(seed=3)
    s = state.copy()
    kernels.step_grid32_serial(s, inv_mass, topo.grid_params, 9.81, 5.0, h, 0,
                               kernels.grid32_work(built, inv_mass, 1, kernels.GRID32_EXACT))
    np.testing.assert_array_equal(s, state)  # not even rounded to float32


def _strike(spec, speed, ticks, backend="numba", nudge=0.0, aim=None):
    """(NetSim, its knot positions after each tick): a ball at `speed` m/s along +x into the net at
    `aim` (y, z) m (None: 1.23 cm right of its middle at mid-height), the ball's path bent by the
    net's contact, for `ticks` ticks; `nudge`: m added to every free knot's y before the strike."""
    sim = NetSim(build_topology(spec), dt=1e-3, backend=backend)
    free = sim.topo.knot_inv_mass > 0
    sim.knot_pos[free, 1] += nudge
    y, z = (0.0123, 0.08) if aim is None else aim
    ball_pos, ball_vel = np.array([-0.03, y, z]), np.array([speed, 0.0, 0.0])
    shapes = np.empty((ticks,) + sim.knot_pos.shape)
    for t in range(ticks):
        contact = sim.step(ball_pos, ball_vel, 0.02, 1.0 / BALL_MASS)
        ball_pos = ball_pos + ball_vel * sim.dt + contact.offset
        ball_vel = ball_vel + contact.impulse / BALL_MASS
        shapes[t] = sim.knot_pos
    return sim, shapes


SMALL = replace(NetSpec(cols=20, rows=5, knot_mass=0.05 / 100), kernel_precision="float32")
SMALL_AIM = (float(build_topology(SMALL).rest_pos[2 * 20 + 10, 1]), float(build_topology(SMALL).rest_pos[2 * 20 + 10, 2]))


def test_a_float32_netsim_equals_its_reference_backend_through_a_strike():
    # Aimed at a free knot: this coarse mesh has gaps wider than the ball.
    fast, fast_shapes = _strike(SMALL, 10.0, 40, aim=SMALL_AIM)
    slow, slow_shapes = _strike(SMALL, 10.0, 40, backend="reference", aim=SMALL_AIM)
    assert fast.awake_ticks == 40 and np.abs(fast.knot_vel).max() > 0.1  # struck, moving
    np.testing.assert_array_equal(fast_shapes, slow_shapes)  # float64 contact, IEEE float32 grid steps: the same bits


def test_a_float32_netsim_steps_free_ticks_as_single_ticks():
    spec = replace(SMALL, kernel_fma=True)
    one, _ = _strike(spec, 10.0, 30, aim=SMALL_AIM)
    many, _ = _strike(spec, 10.0, 30, aim=SMALL_AIM)
    for _ in range(200):
        one.step()
    many.step_free(200)
    np.testing.assert_array_equal(one.knot_pos, many.knot_pos)  # step_grid32_free: NetSim.step's bits
    np.testing.assert_array_equal(one.knot_vel, many.knot_vel)
    assert (one.quiet_ticks, one.sleeping, one.awake_ticks) == (many.quiet_ticks, many.sleeping, many.awake_ticks)


@pytest.mark.parametrize("fma", [False, True])
def test_a_struck_net_rings_in_float32_within_the_budget(fma):
    # The match's 85 x 8 net struck at 5 m/s: every knot within BUDGET of the float64 sim over 3 s.
    spec = resolution_spec(85, 8)
    _, f64 = _strike(spec, 5.0, 3000)
    _, f32 = _strike(replace(spec, kernel_precision="float32", kernel_fma=fma), 5.0, 3000)
    assert np.abs(f32 - f64).max() <= BUDGET  # the 50 µm budget


def test_a_hard_strike_spreads_float32_no_more_than_a_nanometre_spreads_float64():
    # At 20 m/s the struck net's large motion amplifies any difference (1 nm grows to mm within
    # 0.3 s), so no arithmetic path stays within BUDGET of another: float32's spread from float64
    # is held to that of float64 from itself with every free knot moved by 1 nm, within 3x.
    spec = resolution_spec(85, 8)
    _, f64 = _strike(spec, 20.0, 3000)
    _, nudged = _strike(spec, 20.0, 3000, nudge=1e-9)
    _, f32 = _strike(replace(spec, kernel_precision="float32"), 20.0, 3000)
    own = np.abs(nudged - f64).max()
    assert own > BUDGET  # the model's own sensitivity, not float32's
    assert np.abs(f32 - f64).max() <= 3.0 * own  # float32 no worse than a 1 nm nudge, within 3x


def test_kernel_options_are_validated():
    with pytest.raises(ValueError, match="kernel_precision.*one of float64, float32"):
        validate_spec(NetSpec(kernel_precision="float16"))
    with pytest.raises(ValueError, match="kernel_fma.*unless kernel_precision = 'float32'"):
        validate_spec(NetSpec(kernel_fma=True))
    with pytest.raises(ValueError, match="kernel_precision.*semi_implicit solver only"):
        validate_spec(NetSpec(kernel_precision="float32", solver="implicit"))
    with pytest.raises(ValueError, match="kernel_fma.*True or False"):
        validate_spec(NetSpec(kernel_precision="float32", kernel_fma=1))
    with pytest.raises(ValueError, match="needs the grid kernels"):
        NetSim(build_topology(replace(NetSpec(cols=12, rows=4), kernel_precision="float32")), dt=1e-3, grid=False)


def test_a_scene_sets_the_kernel_options():
    base = {"name": "s", "effects": ["gravity", "net"], "dt": 0.001, "duration": 0.01,
            "ball": {"pos": [-1.0, 0.0, 0.3], "vel": [1.0, 0.0, 0.0]}}
    scene = parse_scene(base | {"net": {"kind": "cloth", "cols": 12, "rows": 4, "kernel_precision": "float32",
                                        "kernel_fma": True}}, "s")
    assert (scene.cloth.kernel_precision, scene.cloth.kernel_fma) == ("float32", True)
    with pytest.raises(SceneError, match="net.kernel_precision"):
        parse_scene(base | {"net": {"kind": "cloth", "kernel_precision": "double"}}, "s")
    with pytest.raises(SceneError, match="net.kernel_fma"):
        parse_scene(base | {"net": {"kind": "cloth", "kernel_precision": "float32", "kernel_fma": "yes"}}, "s")
