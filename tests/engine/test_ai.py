"""The bat AI: its inverse problems against the engine's forward model, and play at top skill."""
import pickle

import numpy as np
import pytest

from engine.physics.collision import EVENT_ROW, MAX_IMPACTS_PER_TICK, SCRATCH_SHAPE, ball_tick
from engine.physics.contact import impact
from engine.physics.dtypes import BAT_DTYPE
from engine.physics.geometry import Body
from engine.physics.integrators import ADAPT_SIZE, WORK_SHAPE
from engine.physics.scene import load_scene
from engine.physics.world import build_model
from engine.physics.equipment import NET_HEIGHT
from engine.play.ai import (HALF_LENGTH, HALF_WIDTH, NO_STRIKE, SKILLS, STOP_EVENTS, STOP_RETURN_STRIKE,
                            STOP_SERVE_STRIKE, BatAI, strike_index)
from engine.play.ai.player import think_scratch
from engine.play.ai.search import lands_well
from engine.play.match import LocalAI, Match, make_ais

SCENE = load_scene("match_rigid")


@pytest.fixture(scope="module")
def ai():
    return BatAI(build_model(SCENE), 1, SKILLS["pro"], seed=3)


@pytest.mark.parametrize("target", [(-0.5, 0.0), (-1.0, 0.5), (-0.8, -0.6)])
def test_shot_solution_lands_on_target(ai, target):
    p, spin = np.array([1.6, 0.2, 0.25]), np.array([0.0, -120.0, 0.0])  # topspin for a ball going -x
    v_out = ai.solve_shot(p, spin, target, pace=8.0, end_sign=1)
    _, events = ai._path(p, v_out, spin)
    assert events[0][1] == Body.TABLE
    # Newton stops at 1 mm on the 4 ms flight; the 1 ms path differs by well under 1 mm more.
    np.testing.assert_allclose(events[0][2][:2], target, atol=2e-3)


def test_stroke_inversion_reproduces_the_requested_velocity(ai):
    model = ai.model
    v_in, spin_in = np.array([5.0, 0.3, 1.0]), np.array([0.0, 80.0, 10.0])
    v_out = np.array([-8.0, 0.5, 1.5])
    normal, bat_vel, _ = ai.solve_stroke(v_in, spin_in, v_out)
    got_v, got_w = np.zeros(3), np.zeros(3)
    e, mu = model.materials[Body.BAT_B]
    impact(v_in, spin_in, normal, bat_vel, *model.ball_params[0:3], e, mu, got_v, got_w)
    np.testing.assert_allclose(got_v, v_out, atol=1e-4)  # the fixed point's stopping tolerance
    assert abs(np.linalg.norm(normal) - 1.0) < 1e-12


def test_top_skill_returns_most_serves():
    returned = served = 0
    for seed in range(4):
        match = Match(SCENE, seed=seed)
        points = []
        match.play(max_ticks=12_000, on_point=lambda m, p: points.append(p))
        for p in points:
            if p.shots >= 1:
                served += 1
                returned += p.shots >= 2
    assert served >= 4
    assert returned / served >= 0.7  # most serves returned at high skill


def _incoming_balls(n, seed):
    """Balls struck from A's end towards B's court (end_sign 1): short, long, wide, into the net."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield np.array([-1.5, rng.uniform(-0.5, 0.5), rng.uniform(0.05, 0.45), rng.uniform(3.0, 16.0),
                        rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 3.0), rng.uniform(-50, 50), rng.uniform(-150, 150),
                        rng.uniform(-50, 50)])


def test_strike_search_stops_early_with_the_answer_of_the_whole_path(ai):
    h = ai.model.dt
    n_max = int(round(2.0 / h))
    outcomes = {"none": 0, "strike": 0, "stopped_early": 0}
    for y0 in _incoming_balls(40, seed=5):
        times, traj, events = ai.predict(y0, 2.0, max_events=3)
        want = strike_index(traj.copy(), events, 1, False)
        ticks, _, got, _ = ai._predict(y0, h, n_max, 3, STOP_RETURN_STRIKE, 1)
        assert got == (NO_STRIKE if want is None else want)  # exact: the same rule on the same ticks
        outcomes["none" if want is None else "strike"] += 1
        outcomes["stopped_early"] += ticks < len(times) - 1
    for toss in np.linspace(1.8, 5.0, 5):  # the scene's toss_speed range
        y0 = np.array([1.47, 0.0, 0.12, 0.0, 0.0, toss, 0.0, 0.0, 0.0])
        times, traj, events = ai.predict(y0, 2.0, max_events=3)
        want = strike_index(traj.copy(), events, 1, True)
        assert want is not None and ai._predict(y0, h, n_max, 3, STOP_SERVE_STRIKE, 1)[2] == want
    assert min(outcomes.values()) >= 5, outcomes  # both answers and the early stop were exercised


def test_control_takes_a_record_a_0d_array_or_a_float_row_and_refuses_other_layouts(ai):
    bats = np.zeros(2, BAT_DTYPE)
    bats["quat"] = (1.0, 0.0, 0.0, 0.0)
    bats["pos"][1], bats["vel"][1] = (1.8, 0.1, 0.2), (0.3, -0.2, 0.1)
    ball = np.array([1.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    from_record = ai.control(1.0, ball, bats[1], (0, 0), False, False, 1).copy()
    single = np.zeros((), BAT_DTYPE)
    single[()] = bats[1]
    from_array = ai.control(1.0, ball, single, (0, 0), False, False, 1)
    np.testing.assert_array_equal(from_record, from_array)  # the same numbers, so bit for bit
    rows = bats.view("<f8").reshape(len(bats), -1)
    np.testing.assert_array_equal(ai.control(1.0, ball, rows[1], (0, 0), False, False, 1), from_record)
    assert np.linalg.norm(from_record[0:3]) > 0.0  # the bat is off its ready pose: pulled back
    with pytest.raises(TypeError, match="BAT_DTYPE"):
        ai.control(1.0, ball, bats, (0, 0), False, False, 1)
    with pytest.raises(TypeError, match="BAT_DTYPE"):
        ai.control(1.0, ball, np.zeros(18), (0, 0), False, False, 1)


def _on_court(pos, sign, margin):
    return np.sign(pos[0]) == sign and abs(pos[0]) < HALF_LENGTH - margin and abs(pos[1]) < HALF_WIDTH - margin


def _judge_path(ai, traj, events, end_sign, serve):
    """Whether a whole predicted path lands well, in numpy: the reference of engine.play.ai.search."""
    x = traj[:, 0]
    crossing = np.flatnonzero(np.sign(x[:-1]) != np.sign(x[1:]))
    clearance = -np.inf
    if len(crossing):
        k = crossing[0]
        f = x[k] / (x[k] - x[k + 1])
        clearance = traj[k, 2] + f * (traj[k + 1, 2] - traj[k, 2]) - ai.radius - NET_HEIGHT
    if not events or events[0][1] != Body.TABLE:
        return False
    margin = ai.COURT_MARGIN_M
    if not serve:
        return _on_court(events[0][2], -end_sign, margin) and clearance > ai.NET_MARGIN_M
    if len(events) < 2 or events[1][1] != Body.TABLE:
        return False
    return (_on_court(events[0][2], end_sign, margin) and _on_court(events[1][2], -end_sign, margin)
            and clearance > ai.SERVICE_NET_MARGIN_M)


def test_lands_well_agrees_with_judging_the_predicted_path(ai):
    """Where the free flight is sure, lands_well answers without predicting: the same answers as
    judging the whole predicted path."""
    rng = np.random.default_rng(11)
    answers = {("return", True): 0, ("return", False): 0, ("service", True): 0, ("service", False): 0}

    def compiled(p, v, spin, serve):
        good, err = lands_well(p, v, spin, 1, serve, ai._limits, ai._model_args, ai._search_scratch)
        assert err == 0
        return good

    for _ in range(80):
        p = np.array([rng.uniform(1.3, 2.0), rng.uniform(-0.5, 0.5), rng.uniform(0.05, 0.4)])
        spin = rng.uniform(-150.0, 150.0, 3)
        aim = (-rng.uniform(0.3, 1.6), rng.uniform(-0.9, 0.9))  # some off the court
        v = ai.solve_shot(p, spin, aim, rng.uniform(4.0, 12.0), 1)
        if v is None:
            continue
        v += rng.normal(0.0, 0.3, 3)  # some into the net, some near every limit
        traj, events = ai._path(p, v, spin, max_events=1)
        want = _judge_path(ai, traj, events, 1, False)
        assert compiled(p, v, spin, False) == want
        answers[("return", want)] += 1
    for _ in range(80):
        p = np.array([rng.uniform(1.4, 1.6), rng.uniform(-0.3, 0.3), rng.uniform(0.08, 0.28)])
        spin = rng.uniform(-150.0, 150.0, 3)
        v = ai.solve_shot(p, spin, (rng.uniform(0.3, 1.1), rng.uniform(-0.5, 0.5)), rng.uniform(4.0, 7.5), 1)
        if v is None:
            continue
        v += rng.normal(0.0, 0.2, 3)
        traj, events = ai._path(p, v, spin, max_events=2)
        want = _judge_path(ai, traj, events, 1, True)
        assert compiled(p, v, spin, True) == want
        answers[("service", want)] += 1
    assert min(answers.values()) >= 5, answers  # both answers of both kinds were exercised


def test_prediction_is_ball_tick_bit_for_bit_where_it_steps_free_flight(ai):
    """Far from every body the prediction steps the integrator alone: the same bits as ball_tick."""
    m = ai.model
    work, scratch, adapt = np.zeros(WORK_SHAPE), np.zeros(SCRATCH_SHAPE), np.zeros(ADAPT_SIZE)
    events = np.zeros((MAX_IMPACTS_PER_TICK, EVENT_ROW))
    contacts = 0
    for y0 in _incoming_balls(10, seed=9):
        n, n_events, _, _ = ai._predict(y0, m.dt, 1500, 8, STOP_EVENTS, 0)
        got = ai._traj[: n + 1].copy()
        want = np.empty_like(got)
        want[0] = y0
        support = 0
        adapt[:] = 0.0
        for k in range(n):
            want[k + 1] = want[k]
            _, support = ball_tick(want[k + 1], m.dt, support, m.flight, m.geometry, None,
                                   m.ball_params, m.materials, work, scratch, adapt, events)
        np.testing.assert_array_equal(got, want)  # exact: the same arithmetic
        contacts += n_events
    assert contacts >= 10  # the paths went through bounces, not only free flight


class _SpreadThinking(LocalAI):
    """The AI worker's way: strokes thought out a few steps at a time between control ticks."""

    def __init__(self, ais, seed):
        super().__init__(ais)
        self.rng = np.random.default_rng(seed)

    def request(self, match, now):
        super().request(match, now)
        for ai in self.ais.thinkers:
            for _ in range(int(self.rng.integers(0, 4))):
                ai.think_step()


def test_strokes_thought_out_in_steps_are_the_strokes_thought_out_at_once():
    eager = Match(SCENE, seed=6)
    spread = Match(SCENE, seed=6, ai_driver=_SpreadThinking(make_ais(SCENE, 6, eager=False), 1))
    for _ in range(15_000):
        eager.tick()
        spread.tick()
        assert eager.state.record.tobytes() == spread.state.record.tobytes()
    late = sum(ai.late_thoughts for ai in spread.ai_driver.ais.thinkers)
    assert late > 0 and len(eager.referee.points) >= 2  # some strokes were finished when due


def test_eager_ais_may_share_the_arrays_they_think_in_and_the_others_may_not(ai):
    """Two BatAIs thinking in one set of arrays (a vector environment's tables) think the strokes
    each thinks alone; one that spreads its thinking keeps its own, and a path of another tick is refused."""
    model = ai.model
    shared = think_scratch(model.dt)

    def strokes(share):
        players = [BatAI(model, 1, SKILLS["pro"], seed=s) for s in (4, 5)]
        if share:
            for player in players:
                player.use_scratch(shared)
        out = []
        for y0 in _incoming_balls(6, seed=13):
            for player in players:  # in turns, as the tables' decisions come
                player.planned_key = None
                player._start_thinking(0.0, y0, (0, 1), 1, False)
                out.append(pickle.dumps(player._thought))
        return out

    alone = strokes(False)
    assert strokes(True) == alone
    assert sum(thought != pickle.dumps(None) for thought in alone) >= 4  # strokes were thought out, not let go
    spreading = BatAI(model, 1, SKILLS["pro"], seed=1, eager=False)
    with pytest.raises(ValueError, match="eager=False"):
        spreading.use_scratch(shared)
    with pytest.raises(ValueError, match="think_scratch"):
        BatAI(model, 1, SKILLS["pro"], seed=1).use_scratch(think_scratch(model.dt / 2))
