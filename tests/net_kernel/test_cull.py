"""The culled contact sweep (kernels.collide_ball_near) gives the full sweep's bits: same contacts, same sums."""
import functools

import numpy as np
import pytest

from net_kernel import NetSim, NetSpec, build_topology, kernels, reference
from net_kernel.sim import contact_substeps

BALL_MASS = 2.7e-3  # kg, ITTF 2.3.2
BALL_RADIUS = 0.02  # m, ITTF 2.3.1
KNOT_RADIUS = 0.5e-3  # m, NetSim's default
DT = 1e-3


def _sweep_both(topo, pos, vel, ball_pos, ball_vel, dt, restitution=0.0, inv_mass=None):
    """(full, culled): each (toi, impulse, ball end, knot_pos, knot_vel) from the same start."""
    inv_mass = topo.knot_inv_mass if inv_mass is None else inv_mass
    results = []
    for culled in (False, True):
        p, v = pos.copy(), vel.copy()
        impulse, end = np.zeros(3), np.zeros(3)
        args = (p, v, inv_mass, np.asarray(ball_pos, float), np.asarray(ball_vel, float), BALL_RADIUS,
                1.0 / BALL_MASS, KNOT_RADIUS, restitution, dt, 8, impulse, end)
        if culled:
            toi = kernels.collide_ball_near(*args, np.zeros(topo.n_knots, dtype=np.int64))
        else:
            toi = kernels.collide_ball(*args)
        results.append((toi, impulse, end, p, v))
    return results


def _assert_same_bits(full, culled):
    assert full[0] == culled[0]  # exact: the same time of impact
    for a, b in zip(full[1:], culled[1:]):
        assert np.array_equal(a, b)  # exact: the same knots summed in the same order


@pytest.fixture(scope="module")
def strip():
    """A 0.5 m strip of the default 1 cm mesh, shaken: knots displaced by ~1 mm, moving at ~0.3 m/s."""
    topo = build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass))
    rng = np.random.default_rng(7)
    free = (topo.knot_inv_mass > 0)[:, None]
    pos = topo.knot_pos + free * rng.normal(0.0, 1e-3, topo.knot_pos.shape)
    vel = free * rng.normal(0.0, 0.3, topo.knot_pos.shape)
    return topo, pos, vel


def test_random_hits_and_near_misses_give_the_full_sweeps_bits(strip):
    topo, pos, vel = strip
    rng = np.random.default_rng(11)
    hits = misses = 0
    for _ in range(200):
        # Around the strip's plane (x = 0), within a ball's width of it or a tick's travel away.
        ball_pos = np.array([rng.uniform(-0.06, 0.06), rng.uniform(-0.3, 0.3), rng.uniform(-0.03, 0.18)])
        speed = rng.choice([0.5, 5.0, 20.0, 40.0])
        direction = rng.normal(size=3)
        ball_vel = speed * direction / np.linalg.norm(direction)
        dt = rng.choice([DT / 25, DT])
        full, culled = _sweep_both(topo, pos, vel, ball_pos, ball_vel, dt, restitution=rng.choice([0.0, 0.5]))
        _assert_same_bits(full, culled)
        hits += full[0] >= 0.0
        misses += full[0] < 0.0
    assert hits >= 20 and misses >= 20  # both kinds were exercised (observed: about half each)


def test_rebound_beyond_the_cull_falls_back_to_every_knot(strip):
    """Heavy knots flying at a slow ball at 30 m/s throw it back, onto a knot that the cull left out."""
    topo, pos, _ = strip
    free = topo.knot_inv_mass > 0
    vel = free[:, None] * np.array([-30.0, 0.0, 0.0])
    ball_pos = np.array([-0.025, 0.0, 0.08])
    # One free knot, still, 8 cm behind the ball: outside the cull's box (2 x the ball's 1 mm path
    # + 3 touch distances = 6.9 cm, kernels.collide_ball_near), but in the rebounding ball's way.
    pos = pos.copy()
    behind = int(np.flatnonzero(free)[0])
    pos[behind] = ball_pos + [-0.08, 0.0, 0.0]
    vel[behind] = 0.0
    full, culled = _sweep_both(topo, pos, vel, ball_pos, [0.5, 0.0, 0.0], 2 * DT, restitution=1.0,
                               inv_mass=1e-3 * topo.knot_inv_mass)
    assert full[0] >= 0.0
    assert not np.array_equal(full[4][behind], vel[behind])  # the full sweep's ball struck it
    _assert_same_bits(full, culled)


def test_near_list_too_short_is_refused(strip):
    topo, pos, vel = strip
    for mod in (kernels, reference):
        with pytest.raises(ValueError, match="one int64 per knot"):
            mod.collide_ball_near(pos.copy(), vel.copy(), topo.knot_inv_mass, np.zeros(3), np.ones(3), BALL_RADIUS,
                                  1.0 / BALL_MASS, KNOT_RADIUS, 0.0, DT, 8, np.zeros(3), np.zeros(3),
                                  np.zeros(3, dtype=np.int64))


def _fused_run(topo, ticks, speed, mod=kernels):
    """test_ball's straight ball from 5 cm, ticks stepped by step_grid_ball (far ticks: one step_grid call)."""
    spec = topo.spec
    rows, cols = spec.rows, spec.cols
    sim = NetSim(topo, dt=DT)  # for its substeps, h and far test only
    state = np.zeros((2, 3, rows, cols))
    state[0] = topo.rest_pos.T.reshape(3, rows, cols)
    work = kernels.grid_work(rows, cols)
    ball = np.zeros((4, 3))
    near = np.zeros(topo.n_knots, dtype=np.int64)
    impulse = np.zeros(3)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    pos, vel = np.array([-0.05, 0.0, 0.08]), np.array([speed, 0.0, 0.0])
    tois = []
    for _ in range(ticks):
        if sim.ball_far(pos, vel, BALL_RADIUS):
            mod.step_grid_serial(state, inv_mass, topo.grid_params, spec.gravity, spec.air_damping, sim.h,
                                 sim.substeps, work)
            tois.append(-1.0)
            pos = pos + vel * DT
            continue
        ball[0], ball[1] = pos, vel
        n = contact_substeps(vel, kernels.knot_speed_max(state[0].reshape(3, -1).T, state[1].reshape(3, -1).T), DT,
                             sim.substeps)  # NetSim's substeps with the ball near
        toi = mod.step_grid_ball(state, inv_mass, topo.grid_params, spec.gravity, spec.air_damping, DT / n,
                                 n, work, ball, BALL_RADIUS, 1.0 / BALL_MASS, sim.knot_radius,
                                 sim.restitution, 8, near, impulse)
        tois.append(toi)
        # NetSim's offset: where the ball ended minus its free path's end.
        offset = (ball[0] - pos) - vel * DT if toi >= 0.0 else np.zeros(3)
        pos = pos + vel * DT + offset
        vel = vel + impulse / BALL_MASS
    return state, pos, vel, tois


def _loop_run(topo, ticks, speed, collide):
    """_fused_run's ticks by NetSim's per-substep loop (its arithmetic), with a given contact sweep."""
    spec = topo.spec
    rows, cols = spec.rows, spec.cols
    sim = NetSim(topo, dt=DT)  # for its substeps, h and far test only
    state = np.zeros((2, 3, rows, cols))
    state[0] = topo.rest_pos.T.reshape(3, rows, cols)
    knot_pos, knot_vel = state[0].reshape(3, -1).T, state[1].reshape(3, -1).T
    work = kernels.grid_work(rows, cols)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    hit_impulse, end = np.zeros(3), np.zeros(3)
    pos, vel = np.array([-0.05, 0.0, 0.08]), np.array([speed, 0.0, 0.0])
    tois = []
    for _ in range(ticks):
        if sim.ball_far(pos, vel, BALL_RADIUS):
            kernels.step_grid_serial(state, inv_mass, topo.grid_params, spec.gravity, spec.air_damping, sim.h,
                                     sim.substeps, work)
            tois.append(-1.0)
            pos = pos + vel * DT
            continue
        bp, bv, impulse, toi = pos.copy(), vel.copy(), np.zeros(3), -1.0
        n = contact_substeps(bv, kernels.knot_speed_max(knot_pos, knot_vel), DT, sim.substeps)
        h = DT / n
        for k in range(n):
            hit = collide(knot_pos, knot_vel, topo.knot_inv_mass, bp, bv, BALL_RADIUS, 1.0 / BALL_MASS,
                          sim.knot_radius, sim.restitution, h, 8, hit_impulse, end)
            if hit >= 0.0:
                toi = (k + hit) / n if toi < 0.0 else toi
                impulse += hit_impulse
                bv += hit_impulse * (1.0 / BALL_MASS)
            bp[:] = end
            kernels.step_grid_serial(state, inv_mass, topo.grid_params, spec.gravity, spec.air_damping, h, 1, work)
        tois.append(toi)
        offset = (bp - pos) - vel * DT if toi >= 0.0 else np.zeros(3)
        pos = pos + vel * DT + offset
        vel = vel + impulse / BALL_MASS
    return state, pos, vel, tois


@pytest.mark.parametrize("speed", [20.0, 40.0])
def test_culled_and_fused_ticks_give_the_full_sweeps_bits(speed):
    """test_ball's impact tick by tick: the full sweep, the culled one, and step_grid_ball, all the same bits."""
    topo = build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass))
    near = np.zeros(topo.n_knots, dtype=np.int64)
    full = _loop_run(topo, 15, speed, kernels.collide_ball)
    culled = _loop_run(topo, 15, speed, functools.partial(kernels.collide_ball_near, near=near))
    fused = _fused_run(topo, 15, speed)
    assert sum(t >= 0.0 for t in full[3]) >= 3  # the ball met the net
    for other in (culled, fused):
        assert other[3] == full[3]  # exact: the same times of impact
        for a, b in zip(full[:3], other[:3]):
            assert np.array_equal(a, b)  # exact: knots, ball position and velocity


def test_netsim_gives_the_full_sweeps_bits():
    """NetSim, whichever contact call it makes, steps the impact as the full sweep's loop does."""
    topo = build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass))
    sim = NetSim(topo, dt=DT)
    pos, vel = np.array([-0.05, 0.0, 0.08]), np.array([20.0, 0.0, 0.0])
    tois = []
    for _ in range(15):
        contact = sim.step(pos, vel, BALL_RADIUS, 1.0 / BALL_MASS)
        pos = pos + vel * DT + contact.offset
        vel = vel + contact.impulse / BALL_MASS
        tois.append(contact.toi)
    state, fpos, fvel, ftois = _loop_run(topo, 15, 20.0, kernels.collide_ball)
    assert tois == ftois  # exact
    assert np.array_equal(fpos, pos) and np.array_equal(fvel, vel)  # exact
    assert np.array_equal(state[0].reshape(3, -1).T, sim.knot_pos)  # exact
    assert np.array_equal(state[1].reshape(3, -1).T, sim.knot_vel)  # exact


def test_fused_tick_equals_reference():
    topo = build_topology(NetSpec(width=0.3, cols=31, rows=8, knot_mass=NetSpec().knot_mass * 16 / 8))
    runs = [_fused_run(topo, 6, 20.0, mod) for mod in (kernels, reference)]
    assert sum(t >= 0.0 for t in runs[0][3]) >= 1
    np.testing.assert_allclose(runs[0][3], runs[1][3], rtol=0, atol=1e-12)  # same sums in the same order, to rounding
    for a, b in zip(runs[0][:3], runs[1][:3]):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)  # collide's twin: numpy's sums round alike


def _whole_ticks(topo, mod, ticks, speed):
    """An impact tick by tick with mod.step_grid_tick: per tick (toi, substeps, quiet ticks, status,
    box, impulse, offset), and the knot state after the last."""
    spec = topo.spec
    sim = NetSim(topo, dt=DT)  # for its substeps, reach and scratch only
    state = sim._state.copy()  # noqa: SLF001 (the grid state NetSim steps)
    work = kernels.grid_work(spec.rows, spec.cols)
    ball, near = np.zeros((kernels.TICK_BALL_ROWS, 3)), np.zeros(topo.n_knots, dtype=np.int64)
    box, impulse, offset = np.zeros((2, 3)), np.zeros(3), np.zeros(3)
    pos, vel = np.array([-0.05, 0.0, 0.08]), np.array([speed, 0.0, 0.0])
    quiet, out = 0, []
    for _ in range(ticks):
        ball[4], ball[5] = pos, vel
        toi, taken, quiet, status = mod.step_grid_tick(
            state, topo.knot_inv_mass.reshape(spec.rows, spec.cols), topo.grid_params, spec.gravity, spec.air_damping,
            DT, sim.substeps, work, ball, BALL_RADIUS, 1.0 / BALL_MASS, sim.knot_radius, sim.restitution, 8, near,
            1e-3, 120.0, quiet, 1e-3, sim._reach, box, impulse, offset)  # noqa: SLF001
        out.append((toi, taken, quiet, status, box.copy(), impulse.copy(), offset.copy()))
        pos = pos + vel * DT + offset
        vel = vel + impulse / BALL_MASS
    return out, state


def test_whole_tick_kernel_equals_its_numpy_twin():
    topo = build_topology(NetSpec(width=0.3, cols=31, rows=8, knot_mass=NetSpec().knot_mass * 16 / 8))
    (fast, fast_state), (slow, slow_state) = (_whole_ticks(topo, mod, 6, 20.0) for mod in (kernels, reference))
    assert sum(tick[0] >= 0.0 for tick in fast) >= 1  # the ball met the net
    for a, b in zip(fast, slow):
        assert a[1:4] == b[1:4]  # exact: substeps, quiet ticks, status
        np.testing.assert_allclose(a[0], b[0], rtol=0, atol=1e-12)  # same sums in the same order, to rounding
        for x, y in zip(a[4:], b[4:]):
            np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-12)  # collide's twin: numpy's sums round alike
    np.testing.assert_allclose(fast_state, slow_state, rtol=1e-9, atol=1e-12)  # as test_fused_tick_equals_reference


def test_netsim_whole_tick_gives_the_per_substep_loops_bits():
    """NetSim's one-call tick with the ball near against its per-substep loop (the profile's baseline):
    the same knots, contacts, sleep counts and boxes, through an impact and the ring after it."""
    topo = build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass))
    sims = [NetSim(topo, dt=DT), NetSim(topo, dt=DT)]
    sims[1]._step_grid_tick = None  # noqa: SLF001 (the per-substep loop)
    runs = []
    for sim in sims:
        pos, vel = np.array([-0.05, 0.0, 0.08]), np.array([20.0, 0.0, 0.0])
        ticks = []
        for _ in range(40):  # contact, then the ball slowed and thrown back within reach
            contact = sim.step(pos, vel, BALL_RADIUS, 1.0 / BALL_MASS)
            ticks.append((contact.toi, contact.offset.tolist(), contact.impulse.tolist(), sim.quiet_ticks,
                          sim.box.tolist()))
            pos = pos + vel * DT + contact.offset
            vel = vel + contact.impulse / BALL_MASS
        runs.append((ticks, sim.knot_pos.copy(), sim.knot_vel.copy()))
    assert sum(tick[0] >= 0.0 for tick in runs[0][0]) >= 3  # the ball met the net
    assert runs[0][0] == runs[1][0]  # exact
    assert np.array_equal(runs[0][1], runs[1][1]) and np.array_equal(runs[0][2], runs[1][2])  # exact
