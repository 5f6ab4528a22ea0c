"""Remote players' inputs at the physics: checked again where they are applied, and whatever a
player does with valid inputs, every state the physics publishes is one the wire can encode.

In-process (no served match): the gateway's mailbox and the physics worker's RemoteInputs on
a real Arena, the Match of a served scene stepped tick by tick as the physics worker does.
"""
import math

import numpy as np
import pytest

from engine.physics.bat import (BAT_MAX_SPEED, BAT_MAX_SPIN, HALL_HI_X, HALL_HI_Y, HALL_HI_Z, HALL_LO_X, HALL_LO_Y,
                                HALL_LO_Z)
from engine.physics.scene import load_scene, with_remote_players
from engine.play.match import Match
from processes.network import wire
from processes.runtime import shm
from processes.workers.remote_inputs import remote_input_refusal

REMOTE = frozenset({0, 1})


def test_the_arms_limits_lie_inside_the_wires_ranges():
    assert max(abs(HALL_LO_X), HALL_HI_X, abs(HALL_LO_Y), HALL_HI_Y, abs(HALL_LO_Z), HALL_HI_Z) < wire.MAX_POS_M
    assert BAT_MAX_SPEED < wire.MAX_SPEED_MS and BAT_MAX_SPIN < wire.MAX_BAT_ANG_VEL_RADS


@pytest.mark.parametrize("bat, values, reason", [
    (0, [500.0, 0, 0, 0, 0, 50.0], None),  # the wire's limits are accepted
    (1, [0, 0, 0, 0, 0, 0], None),
    (2, [0, 0, 0, 0, 0, 0], "not_remote_bat"),
    (-1, [0, 0, 0, 0, 0, 0], "not_remote_bat"),
    (0, [math.nan, 0, 0, 0, 0, 0], "non_finite"),
    (1, [0, 0, 0, 0, -math.inf, 0], "non_finite"),
    (0, [300.0, 300.0, 300.0, 0, 0, 0], "force_out_of_range"),  # 520 N
    (0, [1e200, 0, 0, 0, 0, 0], "force_out_of_range"),
    (0, [0, 0, 0, 0, 40.0, 40.0], "torque_out_of_range"),  # 56.6 N m
])
def test_remote_input_refusal(bat, values, reason):
    assert remote_input_refusal(bat, np.array(values, dtype=float), REMOTE) == reason


def test_only_an_ai_bat_is_not_remote():
    """With one remote player, bat b is the AI's: a remote input for it is refused."""
    scene = with_remote_players(load_scene("match_rigid"), 1)
    remote = frozenset(i for i, bat in enumerate(scene.bats) if bat.remote)
    assert remote == {0}
    assert remote_input_refusal(1, np.zeros(6), remote) == "not_remote_bat"


@pytest.fixture
def served(tmp_path, no_leftovers):
    """A served match's Match, the gateway's side of the remote-input mailbox (post) and the
    physics worker's RemoteInputs, on a real Arena and lock table; all closed at the end."""
    from processes.workers.layout import (REMOTE_ACK_DTYPE, REMOTE_ACK_RING, REMOTE_CAPACITY, REMOTE_INPUT_DTYPE,
                                          RUN_LOCK_NAMES)
    from processes.runtime.locks import HOLDER_DTYPE, LockTable
    from processes.runtime.mailbox import MAILBOX_HEADER, Mailbox
    from processes.workers.remote_inputs import RemoteInputs
    from processes.workers.options import RunHandles, RunOptions
    from processes.network.server.config import GatewayConfig

    scene = with_remote_players(load_scene("match_rigid"), 2)
    arena = shm.Arena()
    physics = gateway_locks = None
    try:
        lock_path = str(tmp_path / "locks")
        LockTable.create(lock_path, RUN_LOCK_NAMES, arena.shared_array("lock_holders", HOLDER_DTYPE,
                                                                       len(RUN_LOCK_NAMES))).close()
        arena.shared_array("remote_header", MAILBOX_HEADER, 1)
        arena.shared_array("remote_inputs", REMOTE_INPUT_DTYPE, REMOTE_CAPACITY)
        arena.shared_array("remote_applied", np.dtype("<u8"), 2)
        arena.shared_array("remote_acks", REMOTE_ACK_DTYPE, REMOTE_ACK_RING)
        match = Match(scene, 0)
        physics = RemoteInputs(arena, RunOptions(ticks=0, gateway=GatewayConfig(), handles=RunHandles(lock_path=lock_path)), match)
        gateway_locks = LockTable(lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
        box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], gateway_locks)
        entry = np.zeros((), REMOTE_INPUT_DTYPE)

        def post(bat, seq, values):
            entry["seq"], entry["bat"], entry["inputs"] = seq, bat, values
            assert box.post(entry)

        yield match, post, physics, arena["remote_applied"].array
        del box
    finally:
        if physics is not None:
            physics.close()
        if gateway_locks is not None:
            gateway_locks.close()
        arena.close()


def test_a_bad_remote_input_is_refused_counted_and_never_applied(served):
    match, post, physics, applied = served
    post(0, 1, [10.0, 0, 0, 0, 0, 1.0])
    physics.apply(0)
    before = match.state.bats.tobytes()
    post(0, 2, [math.nan, 0, 0, 0, 0, 0])
    post(1, 3, [0, 0, 0, 0, 0, math.inf])
    post(0, 4, [0, 0, 600.0, 0, 0, 0])
    post(1, 5, [0, 0, 0, 60.0, 0, 0])
    post(7, 6, [0, 0, 0, 0, 0, 0])
    physics.apply(0)
    assert match.state.bats.tobytes() == before  # nothing of them reached a bat ...
    assert applied.tolist() == [1, 0]  # ... nor the acknowledged seqs
    assert match.inputs[0].tolist() == [10.0, 0, 0, 0, 0, 1.0] and not match.inputs[1].any()
    assert dict(physics.refused) == {"non_finite": 2, "force_out_of_range": 1, "torque_out_of_range": 1,
                                     "not_remote_bat": 1}
    post(1, 7, [0, -5.0, 0, 0, 0, 0])  # a good one after them still applies
    physics.apply(0)
    assert match.state.bats["force"][1].tolist() == [0, -5.0, 0] and applied.tolist() == [1, 7]


def test_a_player_pushing_its_bat_to_the_limits_publishes_only_encodable_states(served):
    """The stress runs' unencodable snapshots, in-process: each player drives its bat with valid
    inputs at the wire's limits (force toward the hall's corner, a torque tilted to the face),
    a new input every 10 ms as a bot does, for 3 s of served play; every tick's record (what
    the physics publishes) must encode as a snapshot."""
    match, post, physics, applied = served
    seq = 0
    worst = {"speed": 0.0, "spin": 0.0, "reach": 0.0}
    for tick in range(3000):
        if tick % 10 == 0:
            flip = 1.0 if tick % 400 < 200 else -1.0  # back and forth: into the walls, then spun the other way
            for bat, sign in ((0, -1.0), (1, 1.0)):
                seq += 1
                # 499 N: 500 N can round above the wire's limit
                force = np.array([sign, 0.6 * flip, 0.5]) * 499.0 / math.sqrt(1 + 0.36 + 0.25)
                torque = np.array([30.0 * flip, 0.0, 40.0])
                post(bat, seq, np.concatenate([force, torque]))
        physics.apply(tick)
        match.tick(1)
        record = match.state.record[0]
        wire.snapshot_from_physics(record, seq=tick, input_seq=(0, 0))  # raises WireError if unencodable
        bats = match.state.bats
        worst["speed"] = max(worst["speed"], float(np.linalg.norm(bats["vel"], axis=1).max()))
        worst["spin"] = max(worst["spin"], float(np.linalg.norm(bats["ang_vel"], axis=1).max()))
        worst["reach"] = max(worst["reach"], float(np.abs(bats["pos"][:, 0]).max()))
    assert not physics.refused
    # the inputs did ask for more than an arm gives: the limits acted (reached within rounding)
    assert worst["speed"] == pytest.approx(BAT_MAX_SPEED, rel=1e-12)
    assert worst["spin"] == pytest.approx(BAT_MAX_SPIN, rel=1e-12)
    assert worst["reach"] == HALL_HI_X


def _braked_every_tick(mass, vel_before, force_after):
    """The ticks t (indices of vel_before) whose force is not engine.play.arm's brake from the
    velocity at t's start, bit for bit."""
    from engine.play.arm import brake_force

    out = np.zeros(6)
    return [t for t in range(len(vel_before))
            if brake_force(mass, vel_before[t], out)[0:3].tobytes() != force_after[t].tobytes()]


def test_an_input_holds_its_hold_then_the_physics_brakes_the_bat_every_tick(served):
    match, post, physics, applied = served
    mass = float(match.model.bat_mass[1])
    post(1, 1, [0, 20.0, 0, 0, 0, 0])  # a push on bat B, then nothing more
    hold = physics.hold_ticks
    assert hold == round(0.1 / match.model.dt)  # the gateway's input_hold_s, in ticks
    vel, force = [], []
    for tick in range(3 * hold):
        physics.apply(tick)
        vel.append(match.state.bats["vel"][1].copy())
        match.tick(1)
        force.append(match.state.bats["force"][1].copy())
    assert all(f.tolist() == [0, 20.0, 0] for f in force[:hold])  # held for its hold exactly
    assert _braked_every_tick(mass, vel[hold:], force[hold:]) == []  # then braked from each tick's state
    speed = np.linalg.norm(vel, axis=1)
    assert speed[hold] > 1.0 and np.all(np.diff(speed[hold:]) <= 0.0)  # moving, then never faster
    assert physics.brake_ticks >= 2 * hold


def test_a_still_players_bat_stays_braked_with_the_physics_slowed_on_purpose(no_leftovers):
    # A served match whose seat A nobody takes (it starts at once, players_timeout 0), bat A
    # thrown at 2 m/s, in realtime with every physics tick 2 ms late (about a third of realtime,
    # as on a busy machine): every tick its force is the brake from that tick's own velocity,
    # so it never speeds up but by the ball's touch, and it comes to rest.
    from dataclasses import replace

    from engine.physics.geometry import Body
    from engine.play.arm import BRAKE_PER_S
    from processes.supervisor import Supervisor

    scene = with_remote_players(load_scene("match_rigid"), 1)
    scene = replace(scene, bats=(replace(scene.bats[0], vel=(0.0, 2.0, 0.0)), scene.bats[1]))
    ticks = 1500
    result = Supervisor(scene, ticks, "realtime", trace=True, players_timeout=0.0, crash_worker="physics",
                        slow_turn_s=0.002).run()
    assert result.ticks == ticks and result.workers["physics"]["late_ticks"] > 0  # it did run late
    trace = result.trace[: ticks + 1]
    vel, force = trace["bats"]["vel"][:, 0], trace["bats"]["force"][:, 0]
    assert _braked_every_tick(float(scene.bats[0].mass), vel[:-1], force[1:]) == []
    touched = {int(e["tick"]) for e in result.events if int(e["body"]) == Body.BAT_A}
    speed = np.linalg.norm(vel, axis=1)
    grew = [t for t in range(ticks) if speed[t + 1] > speed[t] and t not in touched]
    assert grew == [], f"bat A sped up without the ball at ticks {grew[:10]}"
    assert speed[0] == 2.0
    # From the last touch (or the start) on only the brake acts: below its clip each tick takes
    # BRAKE_PER_S * dt of the speed away, at the clip more (engine.play.arm), so at the end the speed
    # is at most speed[last] (1 - BRAKE_PER_S dt)^(ticks - last); 1e-9: the float64 steps' rounding.
    last = max(touched, default=-1) + 1
    bound = speed[last] * (1.0 - BRAKE_PER_S * scene.dt) ** (ticks - last)
    assert speed[-1] <= bound * (1 + 1e-9) + 1e-12, f"bat A at {speed[-1]} m/s, above the brake's {bound}"
