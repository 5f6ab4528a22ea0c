"""Runs of ticks near the cloth net (engine.physics.world._run_near_net): the ball stepped ahead of the net
and the ticks after its touch undone give the same bits as a tick at a time."""
from dataclasses import replace

from engine.physics.scene import load_scene
from engine.play.match import Match
from net_kernel import NO_CONTACT


def _counting_runs(match: Match) -> dict:
    """Wrap the match's NetSim.step_run to count its runs, and those cut short by a touch."""
    net = match.state.net_sim
    step_run = net.step_run
    counts = {"runs": 0, "cut": 0, "touched": 0}

    def counted(ball, radius, inv_mass, free_outside):
        taken, contact = step_run(ball, radius, inv_mass, free_outside)
        counts["runs"] += 1
        counts["cut"] += taken < len(ball)
        counts["touched"] += contact.toi != NO_CONTACT
        return taken, contact

    net.step_run = counted
    return counts


def test_the_cloth_match_in_runs_is_the_match_a_tick_at_a_time():
    scene = load_scene("match")
    scene = replace(scene, match=replace(scene.match, best_of=1))
    in_runs, by_tick = Match(scene, seed=0), Match(scene, seed=0)
    counts = _counting_runs(in_runs)
    ticks = 0
    while ticks < 30_000 and not in_runs.over:
        in_runs.tick(1 << 30)
        ticks += in_runs.ticks_done
    for _ in range(ticks):
        by_tick.tick(1)  # one tick a call: every run near the net is one tick long
    # The runs had ticks to undo: a touch before a run's last tick.
    assert counts["cut"] > 0 and counts["touched"] > 0 and counts["runs"] > counts["touched"]
    assert in_runs.state.record.tobytes() == by_tick.state.record.tobytes()
    assert in_runs.state.net_sim.knot_pos.tobytes() == by_tick.state.net_sim.knot_pos.tobytes()
    assert [(p.winner, p.reason, p.shots) for p in in_runs.referee.points] == \
           [(p.winner, p.reason, p.shots) for p in by_tick.referee.points]
