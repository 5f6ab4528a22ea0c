"""The gateway and a player's inputs: its own bat only, forwarded to the physics, never braked here.

A Gateway in this process (the rig fixture) on 127.0.0.1; every wait bounded by the suite's deadline.
"""
import numpy as np

from processes.network import wire
from processes.network.server.gateway import Gateway
from processes.network.wire import MAX_BAD, InputMode, Kind, Slot


def test_a_player_moves_only_its_own_bat_and_the_refusals_are_counted(rig):
    r = rig()
    a, b = r.client(), r.client()
    r.join(a)
    r.join(b)
    a.send_input([1.0, 2.0, 3.0, 0.1, 0.2, 0.3], tick=7)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1)
    a.send_input([5.0, 0, 0, 0, 0, 0], tick=8, slot=Slot.B)  # the other player's bat
    r.settle(lambda: r.gateway.counts["refused.other_bat"] == 1)
    a.send_input([6.0, 0, 0, 0, 0, 0], tick=9)
    watcher = r.client(role="spectator")
    r.join(watcher)
    watcher.send_input([1.0, 0, 0, 0, 0, 0], tick=9, slot=Slot.A)  # a spectator controls nothing
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 2 and r.gateway.counts["refused.spectator_input"] == 1)
    assert r.gateway.counts["refused.other_bat"] == 1
    assert [(bat, tick) for bat, _, tick, _ in r.posted] == [(0, 7), (0, 9)]  # bat 0 = A; nothing for B
    np.testing.assert_array_equal(r.posted[0][3], [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    assert r.posted[1][1] > r.posted[0][1]  # the input's seq rides along, for the snapshot's echo


def test_a_flood_of_inputs_posts_only_the_newest_of_those_that_arrived_together(rig):
    r = rig(remote=(Slot.A,))  # coalescing is the default
    a = r.client()
    r.join(a)
    sent = 300
    for i in range(1, sent + 1):
        a.send_input([float(i), 0, 0, 0, 0, 0], tick=i)
    counts = r.gateway.counts
    r.settle(lambda: counts["inputs_accepted"] + counts["inputs_coalesced"] == sent)  # each one posted or replaced
    seqs = [seq for _, seq, _, _ in r.posted]
    assert seqs == sorted(set(seqs))  # never an older input after a newer one
    assert r.posted[-1][2] == sent and r.posted[-1][3][0] == float(sent)  # the newest one always acts
    assert len(r.posted) == counts["inputs_accepted"] and counts["mailbox_full"] == 0


def _input(seq, force=1.0, slot=Slot.A, mode=InputMode.FORCE, target=(0.0, 0.0, 0.0)):
    force_field = (force, 0.0, 0.0) if mode == InputMode.FORCE else (0.0, 0.0, 0.0)
    quat = (0.0, 0.0, 0.0, 0.0) if mode == InputMode.FORCE else (1.0, 0.0, 0.0, 0.0)
    return wire.encode(Kind.INPUT, seq=seq, tick=seq, slot=slot, mode=mode, force=force_field, torque=(0.0, 0.0, 0.0),
                       target_pos=target, target_quat=quat)


def _mixed_inputs(bad_runs):
    """Valid inputs with, between runs of them, every kind of input the gateway drops or refuses."""
    nan = bytearray(_input(0))
    nan[26:34] = np.float64("nan").tobytes()
    huge = bytearray(_input(0))
    huge[26:34] = np.float64(501.0).tobytes()
    bad = [bytes(nan), bytes(huge), _input(0, slot=Slot.B), _input(0, mode=InputMode.TARGET),
           _input(0)[:-1]]
    messages, seq = [], 0
    for run in range(bad_runs):
        for _ in range(3):
            seq += 1
            messages.append(_input(seq, force=float(seq)))
        messages.append(_input(seq - 1))  # a stale one: replayed
        messages.append(bad[run % len(bad)])
    messages.append(_input(seq + 1, force=float(seq + 1)))
    return messages


def test_coalesced_inputs_are_counted_and_refused_exactly_as_one_by_one(rig):
    # Every message arrives in one read (handle_inputs is what a poll calls with them): drops,
    # refusals, stale replays and the kick come out as they do when each is handled alone, and
    # of each run of valid inputs only the newest is posted, the inputs before a bad one first.
    outcomes = []
    for bad_runs in (12, MAX_BAD + 2):  # the second kicks the session part-way through
        messages = _mixed_inputs(bad_runs)
        for together in (False, True):
            r = rig(remote=(Slot.A,))
            r.join(r.client())
            identity = next(iter(r.gateway.sessions))
            if together:
                r.gateway.handle_inputs([[identity, data] for data in messages])
            else:
                for data in messages:
                    r.gateway.handle([identity, data])
            counts = dict(r.gateway.counts)
            posted = [seq for _, seq, _, _ in r.posted]
            outcomes.append((counts.pop("inputs_accepted", 0) + counts.pop("inputs_coalesced", 0), counts,
                             dict(r.gateway.drops.by_reason), posted))
            r.close()
    for alone, together in (outcomes[0:2], outcomes[2:4]):
        assert together[:3] == alone[:3]  # accepted (posted or replaced), every other count, every drop reason
        assert set(together[3]) <= set(alone[3]) and together[3] == sorted(together[3])
    assert outcomes[0][3][-1] == outcomes[1][3][-1]  # the newest acts
    assert outcomes[2][1]["kicked"] == outcomes[3][1]["kicked"] == 1
    assert len(outcomes[1][3]) == 12 + 1  # one per run of valid inputs (12 runs and the last one)


def test_the_gateway_only_forwards_inputs_the_idle_arm_is_the_physics(rig):
    # The hold and the brake are the physics' (processes.workers.remote_inputs.RemoteInputs): the gateway
    # posts nothing when an input's hold passes, for a moving bat on an empty seat, or as a
    # player leaves.
    r = rig(remote=(Slot.A,), input_hold_s=0.1, timeout_s=5.0)
    r.record["bats"]["vel"][0] = (2.0, 0.0, 0.0)  # bat A moves
    a = r.client()
    r.join(a)
    a.send_input([30.0, 0, 0, 0, 0, 0], tick=3)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1)
    r.clock.now += 1.0  # long past the hold
    for _ in range(5):
        r.step(serve=True)
    a.leave()
    r.settle(lambda: r.gateway.seats[Slot.A].identity is None)
    r.step(serve=True)
    assert len(r.posted) == 1 and r.posted[0][3][0] == 30.0


def test_a_poll_stops_at_its_time_budget_and_the_rest_waits_for_the_next(rig, monkeypatch):
    # POLL_BUDGET_S bounds how long one poll handles messages (the snapshots go out between two
    # polls); the budget is looked at every 8 messages, so with none left a poll handles 8.
    from processes.network.server import gateway as gateway_module

    r = rig(remote=(Slot.A,))
    a = r.client()
    r.join(a)
    monkeypatch.setattr(gateway_module, "POLL_BUDGET_S", 0.0)
    beats = r.gateway.counts["heartbeats_received"]
    for _ in range(40):
        a.send(Kind.HEARTBEAT, ack=0)
    per_poll = []
    while r.gateway.counts["heartbeats_received"] < beats + 40 and len(per_poll) < 10_000:
        per_poll.append(r.gateway.poll(100))
    assert r.gateway.counts["heartbeats_received"] == beats + 40, (per_poll[:20], len(per_poll), dict(r.gateway.counts))
    assert max(per_poll) <= 8  # never more: 40 messages took 5 polls or more
