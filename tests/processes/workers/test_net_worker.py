"""The cloth net in its own worker: lockstep equals the in-process engine bit for bit, and a
SIGKILLed net or physics worker is restarted with the run still exact."""
import tomllib
from pathlib import Path

import pytest

from engine.physics.geometry import Body
from engine.physics.scene import load_scene, parse_scene
from engine.tools.run import run
from processes.supervisor import Supervisor, WorkerFailed, first_difference, workers_for

ROOT = Path(__file__).resolve().parents[3]

# scenes/net.toml with a coarse net (24 x 4 knots, heavier): the same couplings, a fraction of
# the kernel work, so the test stays cheap. The ball hits the net within 0.1 s.
COARSE = {"kind": "cloth", "cols": 24, "rows": 4, "knot_mass": 0.05 / 96}


@pytest.fixture(scope="module")
def net_scene():
    with open(ROOT / "scenes" / "net.toml", "rb") as f:
        data = tomllib.load(f)
    data["net"] = COARSE
    data["duration"] = 0.8
    return parse_scene(data, "net-coarse")


@pytest.fixture(scope="module")
def reference(net_scene):
    return run(net_scene, trace=True)


def test_a_cloth_scene_starts_a_net_worker_and_a_rigid_one_does_not(net_scene):
    assert workers_for(net_scene) == ["physics", "net"]
    assert "net" not in workers_for(load_scene("serve"))


def test_lockstep_with_the_net_worker_equals_the_in_process_engine(net_scene, reference, no_leftovers):
    result = Supervisor(net_scene, net_scene.ticks, "lockstep", trace=True).run()
    assert result.ticks == net_scene.ticks
    assert any(int(e["body"]) == Body.NET for e in reference.events)  # the ball met the cloth
    assert result.workers["net"]["busy_s"] > 0.0  # the net worker stepped it
    physics = result.workers["physics"]
    # The ball met the net (ticks handed over with it) and left its reach (ticks granted without it).
    assert physics["net_ball_ticks"] > 0 and physics["net_free_ticks"] > 0
    assert physics["net_ball_ticks"] + physics["net_free_ticks"] <= net_scene.ticks
    # No AI in this scene: the physics' hand-offs are all waits for the net's answers.
    assert physics["handoff_net_s"] == physics["handoff_s"] > 0.0 and "handoff_ai_s" not in physics
    # The net worker stepped the net awake exactly as often as the in-process net (its cost, the same ticks).
    assert result.workers["net"]["awake_ticks"] == reference.state.net_sim.awake_ticks > 0
    assert first_difference(result.trace, reference.trace) is None
    assert result.events.tobytes() == reference.events.tobytes()


@pytest.mark.parametrize("worker, at", [("net", "contact"), ("net", 150), ("physics", 150)])
def test_a_killed_worker_is_restarted_and_the_cloth_run_stays_exact(worker, at, net_scene, reference, no_leftovers):
    # Tick 150: the net is awake and the ball, thrown back, near it but not touching it; "contact":
    # the ball's first tick in the net.
    tick = int(next(e["tick"] for e in reference.events if int(e["body"]) == Body.NET)) if at == "contact" else at
    result = Supervisor(net_scene, net_scene.ticks, "lockstep", trace=True, crash_at_tick=tick,
                        crash_worker=worker).run()
    assert result.workers[worker]["restarts"] == 1
    assert result.ticks == net_scene.ticks
    assert first_difference(result.trace, reference.trace) is None


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_a_net_answering_late_still_steps_every_tick_exactly(mode, net_scene, reference, no_leftovers):
    # Each ball tick's answer comes 2 ms late and the physics gives a turn again after 0.5 ms
    # without it: the net finds turns given again while it steps them, and the physics goes on
    # past them, as on a busy machine. Every tick is still stepped once, in order, exactly.
    result = Supervisor(net_scene, net_scene.ticks, mode, trace=True, crash_worker="net", handoff_s=0.0005,
                        slow_turn_s=0.002).run()
    assert result.workers["physics"]["net_turns_again"] > 0  # the case under test happened
    assert result.workers["net"]["restarts"] == 0
    assert result.ticks == net_scene.ticks
    assert result.workers["net"]["awake_ticks"] == reference.state.net_sim.awake_ticks
    assert first_difference(result.trace, reference.trace) is None


@pytest.mark.parametrize("worker, at", [("net", "contact"), ("physics", 150)])
def test_a_worker_that_raises_is_restarted_and_the_cloth_run_stays_exact(worker, at, net_scene, reference,
                                                                         no_leftovers):
    # An exception is treated as a death: restarted from the last consistent state, counted.
    tick = int(next(e["tick"] for e in reference.events if int(e["body"]) == Body.NET)) if at == "contact" else at
    result = Supervisor(net_scene, net_scene.ticks, "lockstep", trace=True, crash_at_tick=tick,
                        crash_worker=worker, crash_kind="raise").run()
    assert result.workers[worker]["raised"] == 1 and result.workers[worker]["restarts"] == 1
    assert result.ticks == net_scene.ticks
    assert first_difference(result.trace, reference.trace) is None


def test_a_worker_past_its_restart_budget_ends_the_run_with_its_traceback(net_scene, no_leftovers):
    supervisor = Supervisor(net_scene, net_scene.ticks, "lockstep", crash_at_tick=150, crash_worker="net",
                            crash_kind="raise", restart_budget=0)
    with pytest.raises(WorkerFailed, match=r"(?s)net worker raised InjectedFault: fault injection: raised at tick "
                                           r"150; past its restart budget \(0 restarts within 600 s.*Traceback"):
        supervisor.run()


@pytest.mark.parametrize("crash_at", [None, 150])
def test_lockstep_with_a_float32_net_equals_the_in_process_engine(crash_at, no_leftovers):
    # The float32 grid kernels with fused multiply-adds (NetSpec kernel_precision, kernel_fma): the
    # worker and the in-process engine run the same compiled kernel, so the bits agree, also across
    # a SIGKILLed net worker restarted from its snapshot (tick 150: the net awake, the ball near).
    with open(ROOT / "scenes" / "net.toml", "rb") as f:
        data = tomllib.load(f)
    data["net"] = COARSE | {"kernel_precision": "float32", "kernel_fma": True}
    data["duration"] = 0.8
    scene = parse_scene(data, "net-coarse-float32")
    reference = run(scene, trace=True)
    assert any(int(e["body"]) == Body.NET for e in reference.events)  # the ball met the cloth
    crash = {} if crash_at is None else {"crash_at_tick": crash_at, "crash_worker": "net"}
    result = Supervisor(scene, scene.ticks, "lockstep", trace=True, **crash).run()
    assert result.workers["net"]["restarts"] == (0 if crash_at is None else 1)
    assert first_difference(result.trace, reference.trace) is None
    assert result.events.tobytes() == reference.events.tobytes()


def test_the_net_is_shown_as_the_net_worker_steps_it_also_in_its_tail(no_leftovers):
    """NetShow (what a gateway reads in place of stepping a net of its own): the knots at the tick,
    the tail's rebuilt ones in the linear tail, once every 1/NET_HZ s at most, once asleep."""
    import numpy as np

    from net_kernel import NetSim, build_topology
    from processes.runtime import shm
    from processes.workers.net import NetShow
    from engine.physics.dtypes import net_show_dtype

    scene = load_scene("match")
    topo = build_topology(scene.cloth)
    sim, reference = NetSim(topo, scene.dt), NetSim(topo, scene.dt)
    for net in (sim, reference):  # struck: every free knot moving at 0.3 m/s across the net
        net.wake()
        net.knot_vel[:, 0] = 0.3 * (topo.knot_inv_mass > 0)
    arena = shm.Arena()
    try:
        block = arena.snapshot_block("net_show", net_show_dtype(topo.n_knots), 1)
        show, out = NetShow(block, topo.n_knots, scene.dt), np.zeros(1, net_show_dtype(topo.n_knots))
        shown, tick, tails = [], 0, 0
        while not sim.sleeping and tick < 20_000:
            sim.step_free(4)  # the worker's runs of free ticks, as the physics grants them
            reference.step_free(4)
            tick += 4
            tails += sim.in_tail
            show.publish(sim, tick)
            if block.tick != (shown[-1][0] if shown else None):
                block.snapshot(out)
                shown.append((int(out[0]["tick"]), bool(out[0]["asleep"])))
                np.testing.assert_array_equal(out[0]["pos"], reference.knot_pos)  # the net's own bits
        show.publish(sim, tick + 100)  # asleep: nothing new to show
        assert tails > 0 and sim.sleeping and shown[-1] == (tick, True) and block.tick == tick
        gaps = np.diff([t for t, _ in shown])
        assert gaps[:-1].min() >= show.every and show.every == 16  # 60 Hz at 1 kHz
        del block
    finally:
        arena.close()
