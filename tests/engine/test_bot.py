"""The bot API: what a bot sees, what it may answer, and what a match does when it fails."""
import signal
import time
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.compiled import compile_scene
from engine.play.bot import ACTION_FORCE, BotError, check_action, force, hold, load_bot, new_action
from engine.physics.dtypes import BAT_DTYPE, BAT_STATE_DTYPE, OBSERVATION_DTYPE
from engine.physics.scene import SceneError, load_scene
from engine.play.ai.profile_bot import ProfileBot
from engine.play.arm import ARM_BRAKE, ARM_TARGET, CTL_NORMAL
from engine.play.players import decision_key
from engine.play.match import Match, match_record, match_scene
from engine.play.rules import Reason
from tests import bots

BASE = load_scene("match_rigid")
BUDGET_S = 0.005


def _match(a: str, b: str = "pro", **kwargs) -> Match:
    return Match(match_scene(BASE, a, b, best_of=1), seed=3, budget_s=BUDGET_S, **kwargs)


def test_a_bat_state_is_the_first_fields_of_a_bat_record():
    for name in BAT_STATE_DTYPE.names:
        assert BAT_STATE_DTYPE.fields[name] == BAT_DTYPE.fields[name]
    assert set(OBSERVATION_DTYPE.names) == {"tick", "time", "ball", "own", "other", "score", "games_won", "phase",
                                            "server", "to_strike", "shots", "rally"}


def test_the_engines_ai_plays_through_the_bot_api():
    match = _match("pro", "novice")
    assert all(isinstance(seat.bot, ProfileBot) for seat in match.ais.values())


def test_an_ai_profiles_arm_target_is_checked_as_a_bots_action_is():
    """A profile's seat hands BatAI the state itself, not an observation; what it plans is still
    checked, and a plan that is not a valid arm target, or a decision that raises, is a fault."""
    match = _match("pro", "novice")
    seat = match.ais[0]
    state, rally = match.state, match.state.record[0]["rally"]
    floats = match.ais.bat_floats(state.bats)
    ai, decide = seat.bot.ai, seat.bot.ai.decide

    def bent(*args):
        decide(*args)
        ai._ctl[CTL_NORMAL:CTL_NORMAL + 3] = (2.0, 0.0, 0.0)

    ai.decide = bent
    fault = seat.decide(0, 0.0, state.ball_flat, floats, rally, decision_key(rally))
    assert fault[:2] == (0, "malformed") and "must be unit" in fault[2]
    assert seat.kind == ARM_BRAKE and seat.faults == 1

    def broken(*args):
        raise RuntimeError("prediction failed")

    ai.decide = broken
    fault = seat.decide(0, 0.0, state.ball_flat, floats, rally, decision_key(rally))
    assert fault[:2] == (0, "raised") and "RuntimeError: prediction failed" in fault[2]
    ai.decide = decide
    ai._ctl[CTL_NORMAL:CTL_NORMAL + 3] = (1.0, 0.0, 0.0)  # A's ready pose, as BatAI tracks it
    assert seat.decide(0, 0.0, state.ball_flat, floats, rally, decision_key(rally)) is None
    assert seat.kind == ARM_TARGET and seat.decisions == 3


def test_a_bot_decides_at_every_control_tick_and_sees_a_copy_of_the_state():
    match = _match(bots.spec("Spy"))
    match.play(max_ticks=2000)
    every = match.compiled.control_period
    seen = match.ais[0].bot.seen
    assert len(seen) == 2000 // every  # decisions at ticks 0, every, ... (the last one's force unplayed)
    last = seen[-1]
    assert int(last["tick"]) == 2000 - every
    seat = match.ais[0]
    assert not seat.view.flags.writeable and not np.shares_memory(seat.view, match.state.record)
    assert match.bot_errors == []


def test_a_bot_that_writes_to_its_observation_faults_and_moves_nothing():
    match = _match(bots.spec("Writes"))
    before = match.state.ball.copy()
    match.tick()  # tick 0: the decision is taken (and fails) from the state as tossed
    assert np.array_equal(match.state.ball["pos"][0][:2], before["pos"][0][:2])  # the toss is vertical: x, y stay
    match.play(max_ticks=match.delay + 10)  # the fault reaches the match with the decision, a delay later
    assert match.bot_errors[0]["fault"] == "raised" and "read-only" in match.bot_errors[0]["detail"]


def test_a_raw_force_moves_only_the_bots_own_bat():
    steady = _match(bots.spec("Steady"), "novice")
    other = _match("pro", "novice")
    steady.play(max_ticks=300)  # before the ball reaches B: B's bat moves by its own AI alone
    other.play(max_ticks=300)
    np.testing.assert_array_equal(steady.state.bats[1], other.state.bats[1])
    assert steady.state.bats[0]["vel"][1] > 0.0


@pytest.mark.parametrize("name, fault", [("Raises", "raised"), ("NotANumber", "non_finite"),
                                         ("Oversized", "oversized"), ("Malformed", "malformed"),
                                         ("Overruns", "overran")])
def test_a_failing_bot_gives_the_point_away_and_the_match_goes_on(name, fault):
    match = _match(bots.spec(name))
    result = match.play(max_ticks=6000)
    every = match.compiled.control_period
    first = match.bot_errors[0]
    assert first["fault"] == fault and first["player"] == "a" and first["bot"] == bots.spec(name)
    assert first["tick"] == (bots.FAIL_AT - 1) * every  # the tick of the state it decided from
    faulted = [p for p in match.referee.points if p.reason == Reason.BOT_ERROR]
    assert faulted and all(p.winner == 1 for p in faulted)
    assert result.ticks == 6000 or match.referee.match_over  # it played on
    assert str(BotError(first["bot"], 0, first["tick"], fault, first["detail"])).startswith(
        f"bot {bots.spec(name)} (player A) at tick {first['tick']}: {fault}")


def test_a_decision_that_never_returns_is_interrupted_and_the_outer_alarm_kept():
    # The wall-clock guard runs in any main thread: the hung decisions are faults, the match plays
    # on, and a timer set outside the match (a test runner's own) still fires, later.
    fired = []
    previous = signal.signal(signal.SIGALRM, lambda signum, frame: fired.append(signum))
    signal.setitimer(signal.ITIMER_REAL, 600.0)
    try:
        match = _match(bots.spec("Hangs"))
        match.play(max_ticks=3000)
        outer_left, _ = signal.setitimer(signal.ITIMER_REAL, 0.001)
        deadline = time.monotonic() + 60.0
        while not fired and time.monotonic() < deadline:
            time.sleep(0.01)  # interrupted by the outer alarm, whose handler runs
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    first = match.bot_errors[0]
    assert first["fault"] == "overran" and "interrupted" in first["detail"]
    assert match.referee.winner == 1  # B won the game on A's faults
    assert 0.0 < outer_left < 600.0 and fired == [signal.SIGALRM]


def test_a_failing_bot_stops_the_match_when_told_to():
    match = _match(bots.spec("Raises"), on_bot_error="stop")
    result = match.play(max_ticks=6000)
    every = match.compiled.control_period
    assert match.stopped is not None and len(match.bot_errors) == 1
    assert result.ticks == (bots.FAIL_AT - 1) * every + match.delay  # stopped when the failed decision took effect
    assert "RuntimeError: no idea what to do" in result.stopped


def test_the_failed_decisions_are_in_the_match_record():
    record = match_record(BASE, 3, bots.spec("Oversized"), "novice", best_of=1, max_ticks=3000, budget_s=BUDGET_S)
    assert record["bot_errors"][0] == {"player": "a", "bot": bots.spec("Oversized"),
                                       "tick": (bots.FAIL_AT - 1) * compile_scene(BASE).control_period, "fault": "oversized"}
    assert record["reasons"]["a"].get("bot_error", 0) >= 1 and not record["stopped"]


def test_actions_are_checked_against_the_arms_limits():
    assert check_action(force((119.0, 0.0, 0.0), (0.0, 0.0, 3.9)), 120.0, 4.0) is None
    assert check_action(force((0.0, 121.0, 0.0)), 120.0, 4.0)[0] == "oversized"
    assert check_action(force((0.0, 0.0, 0.0), (0.0, 4.5, 0.0)), 120.0, 4.0)[0] == "oversized"
    assert check_action(hold((1.0, 0.0, 0.1), (1.0, 0.0, 0.0)), 120.0, 4.0) is None
    bad = new_action()
    bad["normal"] = (2.0, 0.0, 0.0)
    assert check_action(bad, 120.0, 4.0)[0] == "malformed"
    bad = new_action()
    bad["n_segments"] = 1  # a segment from t0 = 0 to t1 = 0
    assert check_action(bad, 120.0, 4.0)[0] == "malformed"
    bad = new_action()
    bad["kind"] = 7
    assert check_action(bad, 120.0, 4.0)[0] == "malformed"
    bad = hold((np.inf, 0.0, 0.1), (1.0, 0.0, 0.0))
    assert check_action(bad, 120.0, 4.0)[0] == "non_finite"
    assert check_action(np.zeros(3), 120.0, 4.0)[0] == "malformed"
    assert int(force((1.0, 0.0, 0.0))["kind"]) == ACTION_FORCE


def test_a_bad_bot_spec_says_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="no file"):
        load_bot("no/such/file.py:Bot")
    with pytest.raises(ValueError, match="must be a subclass of engine.play.bot.Bot"):
        load_bot(bots.spec("NotABot"))
    with pytest.raises(ValueError, match="FILE.py:ClassName"):
        load_bot("just-a-name:")
    broken = tmp_path / "broken.py"
    broken.write_text("def oops(:\n")
    with pytest.raises(ValueError, match="raised while loading: SyntaxError"):
        load_bot(f"{broken}:Bot")
    with pytest.raises(SceneError, match="a bot"):
        match_scene(BASE, "grandmaster", "pro")


def test_a_file_bot_imports_the_modules_beside_it(tmp_path):
    (tmp_path / "pp_helper_beside.py").write_text("X = 1.6\n")
    (tmp_path / "pp_helper_later.py").write_text("Z = 0.2\n")
    (tmp_path / "hbot.py").write_text(
        "from engine.play.bot import Bot, hold\n"
        "from pp_helper_beside import X\n"
        "class HBot(Bot):\n"
        "    def act(self, obs):\n"
        "        from pp_helper_later import Z  # imported when it plays, not when it loads\n"
        "        return hold((self.end_sign * X, 0.0, Z), self.normal)\n")
    cls = load_bot(f"{tmp_path / 'hbot.py'}:HBot")
    bot = cls()
    bot.end_sign, bot.normal = 1, np.array([-1.0, 0.0, 0.0])
    assert tuple(bot.act(None)["hold"]) == (1.6, 0.0, 0.2)


@pytest.mark.parametrize("latency, delay", [(0.0, 10), (0.02, 20), (0.05, 50), (0.054, 50)])
def test_an_action_is_played_from_the_control_tick_a_decision_latency_later(latency, delay):
    # Steady decides a raw force from tick 0 on; before its first decision takes effect the idle
    # arm brakes the bat at rest (no force). The latency counts in whole control periods, at least one.
    scene = match_scene(BASE, bots.spec("Steady"), "pro", best_of=1)
    scene = replace(scene, match=replace(scene.match, decision_latency=latency))
    match = Match(scene, seed=3, budget_s=BUDGET_S)
    assert match.delay == delay
    forces = []
    for _ in range(delay + 10):
        match.tick(1)
        forces.append(float(match.state.bats["force"][0][1]))
    assert forces[:delay] == [0.0] * delay and forces[delay] == 0.5  # the action's force, from tick `delay` on
