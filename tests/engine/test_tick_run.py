"""engine.physics.tick.advance_run, the kernel of a run of ticks near the cloth net: the same ticks as
advance_ticks one at a time, with the ball kept at each tick's start and the record after each."""
import math

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.physics.tick import ERR_BATS_BEFORE, STOP_LIMIT
from engine.physics.world import (
    SimulationError,
    _advance_kernel,
    _advance_run_kernel,
    _run_near_net,
    build_model,
    initial_state,
    new_events,
)


def _over_the_net():
    """The match scene's state with the ball 0.3 m short of the net, 10 cm above its top, at 10 m/s towards B."""
    scene = load_scene("match")
    model = build_model(scene)
    state = initial_state(scene)
    state.ball_flat[0:3] = (-0.3, 0.0, 0.2525)
    state.ball_flat[3:6] = (10.0, 0.0, 0.0)
    state.ball_flat[6:9] = 0.0
    return model, state


def test_a_run_is_the_ticks_one_at_a_time_and_keeps_each_start_and_record():
    model, run = _over_the_net()
    _, single = _over_the_net()
    h = model.dt
    ticks, n, reason, error = _advance_run_kernel(model, run, 16, h, math.inf, -math.inf, math.inf)
    assert error == 0 and n == 0 and reason == STOP_LIMIT and ticks == 16  # 16 cm in 16 ticks: still in reach
    events = new_events()
    for k in range(ticks):
        assert run.run_ball[k, 0].tobytes() == single.ball_flat[0:3].tobytes()  # the ball at the tick's start
        assert run.run_ball[k, 1].tobytes() == single.ball_flat[3:6].tobytes()
        _advance_kernel(model, single, 1, None, events, h, math.inf, -math.inf, math.inf, None)
        assert run.run_bytes[k].tobytes() == single.record.view(np.uint8).tobytes()  # the record after it
    assert run.record.tobytes() == single.record.tobytes()


def test_a_run_ends_after_the_tick_that_leaves_the_nets_reach():
    model, state = _over_the_net()
    reach_x = float(model.cloth_reach[3])  # the reach's far face along x
    rows = state.run_ball.shape[0]
    for _ in range(100):  # runs of at most `rows` ticks, asked for more: the kernel keeps to its rows
        ticks, _, reason, error = _advance_run_kernel(model, state, 10 * rows, model.dt, math.inf, -math.inf,
                                                      math.inf)
        assert error == 0 and reason == STOP_LIMIT and 1 <= ticks <= rows
        if float(state.ball_flat[0]) > reach_x:
            break
    x_before_last = float(state.run_ball[ticks - 1, 0, 0])
    assert x_before_last <= reach_x < float(state.ball_flat[0])  # the last tick carried the ball out, not one before


def test_a_bat_not_finite_before_the_run_steps_nothing_and_is_named():
    model, state = _over_the_net()
    state.bat_flat[0, 0] = np.nan
    before = state.record.tobytes()
    ticks, _, _, error = _advance_run_kernel(model, state, 16, model.dt, math.inf, -math.inf, math.inf)
    assert (ticks, error) == (0, ERR_BATS_BEFORE) and state.record.tobytes() == before
    with pytest.raises(SimulationError, match="before the tick; nothing was stepped"):
        _run_near_net(model, state, 16, None, new_events(), model.dt, math.inf, -math.inf, math.inf)
