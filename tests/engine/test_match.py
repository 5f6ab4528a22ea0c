"""The in-process match: seeded and reproducible, judged, with the summary fields users read."""
import pickle
from dataclasses import replace

import pytest

from engine.physics.scene import SceneError, load_scene, parse_scene
from engine.play.match import Match, match_scene
from tests import bots

SCENE = load_scene("match_rigid")


def play(seed, ticks):
    match = Match(SCENE, seed=seed)
    result = match.play(max_ticks=ticks)
    return match, result


def test_a_seeded_match_is_reproducible_bit_for_bit():
    first, r1 = play(7, 15_000)
    second, r2 = play(7, 15_000)
    assert first.state.ball.tobytes() == second.state.ball.tobytes()
    assert first.state.bats.tobytes() == second.state.bats.tobytes()
    assert [(p.winner, p.reason, p.shots) for p in first.referee.points] == \
           [(p.winner, p.reason, p.shots) for p in second.referee.points]
    assert r1.summary()["points"] == r2.summary()["points"] > 0


def test_summary_fields():
    _, result = play(1, 8_000)
    summary = result.summary()
    for key in ("winner", "games", "points", "mean_rally_shots", "realtime_factor", "point_reasons",
                "serves_returned", "sim_seconds", "wall_seconds"):
        assert key in summary
    assert summary["sim_seconds"] == pytest.approx(8.0)


def test_short_match_is_won():
    scene = replace(SCENE, match=replace(SCENE.match, best_of=1))
    match = Match(scene, seed=2)
    result = match.play(max_ticks=600_000)
    summary = result.summary()
    assert summary["winner"] in ("a", "b")
    a, b = summary["games"][0]
    assert max(a, b) >= 11 and abs(a - b) >= 2  # a game to 11, won by two


def test_match_needs_a_referee():
    with pytest.raises(ValueError, match="has no referee"):
        Match(load_scene("rally"))


def test_referee_needs_the_whole_table():
    with pytest.raises(SceneError, match="effect 'referee' needs the table, net, floor and both bats; missing: net"):
        parse_scene({"effects": ["gravity", "table", "floor", "bats", "referee"], "ball": {"pos": [0, 0, 0.3]},
                     "bats": {"a": {"pos": [-1.7, 0, 0.1]}, "b": {"pos": [1.7, 0, 0.1]}}}, "inline")


def test_advancing_in_chunks_gives_the_same_match_as_tick_by_tick():
    chunked, by_tick = Match(SCENE, seed=4), Match(SCENE, seed=4)
    ticks = 0
    while ticks < 12_000:
        chunked.tick(1 << 30)
        ticks += chunked.ticks_done
    for _ in range(ticks):
        by_tick.tick(1)
    assert chunked.state.record.tobytes() == by_tick.state.record.tobytes()
    assert [(p.winner, p.reason, p.shots) for p in chunked.referee.points] == \
           [(p.winner, p.reason, p.shots) for p in by_tick.referee.points]


@pytest.mark.parametrize("players", [("pro", "novice"), (bots.spec("Spy"), "novice")])
def test_a_renewed_match_is_the_new_match_of_its_seed_bit_for_bit(players):
    """Match.renew (what an environment's next episode does) keeps the profiles' arrays and
    nothing else: the match it begins is Match(compiled, seed)'s."""
    renewed = Match(match_scene(SCENE, *players), seed=3)
    renewed.play(max_ticks=6_000)
    renewed.renew(8)
    fresh = Match(renewed.compiled, seed=8)
    for match in (renewed, fresh):
        match.play(max_ticks=9_000)
    assert renewed.state.record.tobytes() == fresh.state.record.tobytes()
    assert [(p.winner, p.reason, p.shots) for p in renewed.referee.points] == \
           [(p.winner, p.reason, p.shots) for p in fresh.referee.points]

    def decided(match):  # what the players decided on, less the CPU and wall seconds they took
        return pickle.dumps({player: ({**seat.bot.ai.state(), "late_thinking_s": 0.0} if seat.profile else
                                      (seat.key, seat.decisions, seat.faults, len(seat.bot.seen)))
                             for player, seat in match.ais.items()})

    assert decided(renewed) == decided(fresh)
    assert (renewed.ais.ctl == fresh.ais.ctl).all() and renewed.bot_errors == fresh.bot_errors == []
