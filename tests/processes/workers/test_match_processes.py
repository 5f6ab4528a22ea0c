"""The multi-process match (the default scene: the cloth net in its worker): physics, net and AI workers
reproduce the in-process match bit for bit."""
import numpy as np
import pytest

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.geometry import Body
from engine.physics.scene import load_scene
from engine.play.match import Match, point_row
from engine.tools.replay import read, write
from processes.supervisor import Supervisor, first_difference, workers_for

SCENE = load_scene("match")
TICKS = 12_000


def reference_trace(seed, ticks, tail=None, in_flight=None):
    """(match, trace) of the in-process match; `tail`, a (ticks + 1,) bool array if given, gets
    whether its cloth net was in its linear tail after each tick; `in_flight`, a (ticks + 1,) int
    array if given, how many decisions that change a plan were in flight after each tick (taken,
    their plans not yet in effect: the AI worker was given a turn for each)."""
    match = Match(SCENE, seed=seed)
    trace = np.zeros(ticks + 1, physics_snapshot_dtype(len(SCENE.bats)))
    match.save(trace, 0)
    for k in range(ticks):
        match.tick()
        match.save(trace, k + 1)
        if tail is not None:
            tail[k + 1] = match.state.net_sim.in_tail
        if in_flight is not None:
            plans = [match.arm] + [entry[1] for entry in match.ai_driver.pending]
            in_flight[k + 1] = sum(not np.array_equal(a, b) for a, b in zip(plans, plans[1:]))
    return match, trace


def first_net_touch(seed: int, ticks: int) -> int:
    """The tick of the in-process match's first contact with the cloth net."""
    match = Match(SCENE, seed=seed)
    while int(match.state.world[0]["tick"]) < ticks:
        match.tick()
        if any(int(ev["body"]) == Body.NET for ev in match.events[:match.n_events]):
            return int(match.state.world[0]["tick"]) - 1
    raise AssertionError(f"seed {seed}: the ball does not touch the net in {ticks} ticks")


def test_an_ai_scene_starts_an_ai_worker_and_a_plain_one_does_not():
    assert workers_for(SCENE) == ["physics", "net", "ai"]
    assert workers_for(load_scene("match_rigid")) == ["physics", "ai"]
    assert workers_for(load_scene("rally")) == ["physics"]


@pytest.mark.parametrize("gate_ai_turns", [False, True])
def test_lockstep_match_equals_the_in_process_match_bit_for_bit(no_leftovers, gate_ai_turns):
    """Also with the AI's turns given only where a player could decide (RunOptions.gate_ai_turns)."""
    result = Supervisor(SCENE, TICKS, "lockstep", trace=True, seed=5, gate_ai_turns=gate_ai_turns).run()
    match, trace = reference_trace(5, TICKS)
    assert first_difference(result.trace, trace) is None
    assert len(result.points) == len(match.referee.points) > 0
    expected = np.array([point_row(p, 0) for p in match.referee.points])
    np.testing.assert_array_equal(result.points[["winner", "reason", "shots", "score_after"]],
                                  expected[["winner", "reason", "shots", "score_after"]])
    physics = result.workers["physics"]
    assert physics["ai_turns"] + physics["ai_skipped"] == TICKS // match.ai_every
    assert (physics["ai_skipped"] > 0) == gate_ai_turns


# A physics worker killed with no decision in flight, with one and with two (taken up from the
# AI's rings), at the first such tick after 4000 of seed 5's match; one that raises (any
# exception) is restarted as one that dies.
@pytest.mark.parametrize("in_flight, kind", [(0, "kill"), (1, "kill"), (2, "kill"), (1, "raise")])
def test_physics_worker_killed_mid_match_resumes_and_stays_exact(no_leftovers, in_flight, kind):
    flights = np.zeros(TICKS + 1, np.int64)
    _, trace = reference_trace(5, TICKS, in_flight=flights)
    crash_at = 4000 + int(np.argmax(flights[4000:] == in_flight))
    assert flights[crash_at] == in_flight, f"seed 5 has no tick after 4000 with {in_flight} decisions in flight"
    result = Supervisor(SCENE, TICKS, "lockstep", trace=True, seed=5, crash_at_tick=crash_at, crash_kind=kind).run()
    assert result.workers["physics"]["restarts"] == 1
    assert result.workers["physics"]["raised"] == (kind == "raise")
    assert first_difference(result.trace, trace) is None


def test_net_worker_killed_mid_match_resumes_and_stays_exact(no_leftovers):
    # SIGKILLed as the ball first meets the net (before that the net sleeps): the restarted
    # worker resumes from the state it published and the match goes on as in process.
    touch = first_net_touch(5, 40_000)
    ticks = touch + 500
    _, trace = reference_trace(5, ticks)
    result = Supervisor(SCENE, ticks, "lockstep", trace=True, seed=5, crash_at_tick=touch,
                        crash_worker="net").run()
    assert result.workers["net"]["restarts"] == 1
    assert first_difference(result.trace, trace) is None


# Seed 2's net is struck early and holds its ring in its linear tail from about tick 2700 to 5000.
TAIL_KILL, TAIL_TICKS = 4_000, 5_200


def test_net_worker_killed_in_its_linear_tail_resumes_and_stays_exact(no_leftovers):
    # The tail's state is a function of its start and its ticks alone: the net worker restarted
    # from the tail it published goes on with the same bits, and so does the whole match.
    tail = np.zeros(TAIL_TICKS + 1, bool)
    reference, trace = reference_trace(2, TAIL_TICKS, tail)
    assert tail[TAIL_KILL] and reference.state.net_sim.tail_ticks > 0, "the net was not in its tail at the kill"
    plain = Supervisor(SCENE, TAIL_TICKS, "lockstep", trace=True, seed=2).run()
    assert first_difference(plain.trace, trace) is None
    assert plain.workers["net"]["tail_ticks"] == reference.state.net_sim.tail_ticks
    assert plain.workers["net"]["awake_ticks"] == reference.state.net_sim.awake_ticks
    killed = Supervisor(SCENE, TAIL_TICKS, "lockstep", trace=True, seed=2, crash_at_tick=TAIL_KILL,
                        crash_worker="net").run()
    assert killed.workers["net"]["restarts"] == 1
    assert first_difference(killed.trace, trace) is None


def test_net_worker_killed_stepping_its_last_tail_ticks_is_restarted_and_stops(no_leftovers):
    # The physics grants a tail's ticks and wakes the net worker only every TAIL_NUDGE_TICKS, so
    # the worker steps the last of them when told to stop, and is killed doing so: the worker
    # that replaces it never gets that wake-up, reads the stop from the baton, and the run ends
    # (the baton's run: a speculating net worker is tested in test_speculation.py).
    result = Supervisor(SCENE, TAIL_KILL, "lockstep", seed=2, crash_at_tick=TAIL_KILL - 1, crash_worker="net",
                        speculate=False).run()
    assert result.workers["net"]["restarts"] == 1
    assert result.ticks == TAIL_KILL


# The AI worker keeps its players' state after every AI_KEEP_EVERY = 8th turn and journals the
# turns since: killed after its first turn at or after these ticks of seed 5's match (early,
# with strokes still being thought out, and later), it restarts from the state kept, decides
# the journal's later turns again and goes on from the queue's counts.
@pytest.mark.parametrize("crash_at", [1720, 2000, 4170])
def test_ai_worker_killed_mid_match_resumes_and_stays_exact(no_leftovers, crash_at):
    result = Supervisor(SCENE, 6_000, "lockstep", trace=True, seed=5, crash_at_tick=crash_at, crash_worker="ai").run()
    assert result.workers["ai"]["restarts"] == 1
    assert result.ticks == 6_000
    _, trace = reference_trace(5, 6_000)
    assert first_difference(result.trace, trace) is None


def test_replay_round_trip(tmp_path):
    result = Supervisor(SCENE, 3_000, "lockstep", seed=1, frame_every=10).run()
    path = tmp_path / "m.replay"
    write(path, scene_name="match", scene_text="", seed=1, dt=SCENE.dt, frame_every=10, frames=result.frames,
          events=result.events, points=result.points, summary={"winner": None})
    back = read(path)
    assert back.header["version"] == 1 and back.header["seed"] == 1
    assert back.frames.tobytes() == result.frames.tobytes()
    assert back.events.tobytes() == result.events.tobytes()
    assert back.points.tobytes() == result.points.tobytes()
