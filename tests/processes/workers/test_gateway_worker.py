"""The gateway worker's side of a served run: the workers a remote seat needs (and the scene's
rule for one), and a snapshot that acknowledges exactly the inputs applied before its tick.
"""
import tomllib

import numpy as np
import pytest

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.scene import SceneError, load_scene, parse_scene, with_remote_players
from processes.runtime import shm
from processes.network.server.config import GatewayConfig
from processes.supervisor import workers_for
from tests.helpers.commands import ROOT


def test_serving_a_scene_makes_its_bats_remote_and_starts_a_gateway():
    scene = load_scene("match_rigid")
    one, two = with_remote_players(scene, 1), with_remote_players(scene, 2)
    assert [b.remote for b in one.bats] == [True, False] and one.bats[1].skill == "pro"
    assert workers_for(one) == ["physics", "ai", "gateway"]
    assert workers_for(two) == ["physics", "gateway"] and "ai" not in two.effects
    assert workers_for(scene) == ["physics", "ai"]
    with pytest.raises(SceneError):
        with_remote_players(load_scene("rally"), 1)


# --- acknowledged input seqs: a snapshot names exactly the inputs it shows --------------------
def test_a_snapshot_acknowledges_the_inputs_applied_before_its_tick_not_the_next_ones(tmp_path, no_leftovers):
    """The physics applies an input after publishing tick T (for the step T -> T+1); a gateway
    reading tick T's snapshot right then must still say the previous seq (the bug this replaced:
    it read the live 'applied' seqs, one tick ahead of the snapshot)."""
    from engine.play.match import Match
    from processes.workers.gateway import _consistent_snapshot
    from processes.workers.layout import (REMOTE_ACK_DTYPE, REMOTE_ACK_RING, REMOTE_CAPACITY, REMOTE_INPUT_DTYPE,
                                          RUN_LOCK_NAMES, read_ack, write_ack)
    from processes.runtime.locks import HOLDER_DTYPE, LockTable
    from processes.runtime.mailbox import MAILBOX_HEADER, Mailbox
    from processes.workers.remote_inputs import RemoteInputs
    from processes.workers.options import RunHandles, RunOptions

    scene = with_remote_players(load_scene("match_rigid"), 2)
    arena = shm.Arena()
    try:
        snapshots = arena.snapshot_block("physics", physics_snapshot_dtype(2), 1)
        lock_path = str(tmp_path / "locks")
        LockTable.create(lock_path, RUN_LOCK_NAMES, arena.shared_array("lock_holders", HOLDER_DTYPE,
                                                                       len(RUN_LOCK_NAMES))).close()
        arena.shared_array("remote_header", MAILBOX_HEADER, 1)
        arena.shared_array("remote_inputs", REMOTE_INPUT_DTYPE, REMOTE_CAPACITY)
        applied = arena.shared_array("remote_applied", np.dtype("<u8"), 2).array
        acks = arena.shared_array("remote_acks", REMOTE_ACK_DTYPE, REMOTE_ACK_RING).array
        match = Match(scene, 0)
        physics = RemoteInputs(arena, RunOptions(ticks=0, gateway=GatewayConfig(), handles=RunHandles(lock_path=lock_path)), match)
        gateway_locks = LockTable(lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
        box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], gateway_locks)
        post = np.zeros((), REMOTE_INPUT_DTYPE)
        record = np.zeros(1, physics_snapshot_dtype(2))

        def send(seq, force_x):
            post["seq"], post["bat"], post["inputs"] = seq, 0, (force_x, 0, 0, 0, 0, 0)
            assert box.post(post)

        def physics_tick(tick):  # the worker's order: apply, step (the tick advances), ack, publish
            physics.apply(tick - 1)
            match.state.world[0]["tick"] = tick
            physics.publish_ack(tick)
            snapshots.publish(match.state.record, tick)

        send(4, 1.0)
        physics_tick(1)
        send(5, 2.0)
        physics.apply(1)  # the next tick's input is applied right after tick 1 was published ...
        assert int(applied[0]) == 5  # ... which the live seqs already show
        rec, ack = _consistent_snapshot(snapshots, acks, record)
        assert int(rec["world"]["tick"]) == 1 and ack == (4, 0)
        assert float(rec["bats"]["force"][0][0]) == 1.0  # the snapshot holds seq 4's force, as acknowledged
        match.state.world[0]["tick"] = 2
        physics.publish_ack(2)
        snapshots.publish(match.state.record, 2)
        rec, ack = _consistent_snapshot(snapshots, acks, record)
        assert int(rec["world"]["tick"]) == 2 and ack == (5, 0) and float(rec["bats"]["force"][0][0]) == 2.0
        write_ack(acks, 2 + REMOTE_ACK_RING, (6, 0))  # a ring later the entry of tick 2 is gone
        assert read_ack(acks, 2) is None and read_ack(acks, 2 + REMOTE_ACK_RING) == (6, 0)
        physics.close()
        gateway_locks.close()
        del applied, acks, box, match, physics
    finally:
        arena.close()


def test_a_remote_bat_needs_the_effect_and_no_skill():
    data = tomllib.loads((ROOT / "scenes" / "match_rigid.toml").read_text())
    data["bats"]["a"]["remote"] = True
    with pytest.raises(SceneError, match="either by the AI"):
        parse_scene(data, "t.toml")
    del data["bats"]["a"]["skill"]
    with pytest.raises(SceneError, match="needs the effect 'remote'"):
        parse_scene(data, "t.toml")
    data["effects"].append("remote")
    scene = parse_scene(data, "t.toml")
    assert scene.bats[0].remote and workers_for(scene) == ["physics", "ai", "gateway"]
