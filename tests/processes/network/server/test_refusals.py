"""What the gateway refuses: malformed messages, a malformed hello, target mode; dropped, counted, never fatal.

A Gateway in this process (the rig fixture); every wait bounded by the suite's deadline.
"""
import numpy as np

from processes.network import wire
from processes.network.server.gateway import Gateway
from processes.network.wire import GoodbyeReason, Kind, RejectReason, Role, Slot


def _good_input(seq=1):
    return bytearray(wire.encode(Kind.INPUT, seq=seq, tick=1, slot=Slot.A, mode=wire.InputMode.FORCE,
                                 force=[1.0, 0, 0], torque=[0, 0, 0], target_pos=[0, 0, 0],
                                 target_quat=[0, 0, 0, 0]))


def _malformed() -> dict:
    good = _good_input()
    wrong_version = bytearray(good)
    wrong_version[4:6] = (9).to_bytes(2, "little")
    wrong_type = bytearray(good)
    wrong_type[6] = 99
    nan = bytearray(good)
    nan[26:34] = np.float64("nan").tobytes()
    out_of_range = bytearray(good)
    out_of_range[26:34] = np.float64(1e6).tobytes()
    return {"too_short": bytes(good[:20]), "too_long": bytes(good) + b"\0", "bad_version": bytes(wrong_version),
            "unknown_type": bytes(wrong_type), "non_finite": bytes(nan), "out_of_range": bytes(out_of_range),
            "bad_magic": b"XXXX" + bytes(good[4:])}


def test_malformed_messages_are_dropped_counted_and_never_fatal(rig):
    r = rig()
    player = r.client()
    r.join(player)
    bad = _malformed()
    for data in bad.values():
        player.send_raw(data)
    player.sock.send_multipart([bytes(_good_input(50)), b"extra"])  # two frames: not one message
    stranger = r.client()
    stranger.send_raw(bytes(_good_input()))  # valid, but no session
    r.settle(lambda: r.gateway.stats()["dropped_total"] == len(bad) + 2)
    stats = r.gateway.stats()
    for reason in bad:
        assert stats[f"dropped.{reason}"] == 1, reason
    assert stats["dropped.bad_framing"] == 1 and stats["dropped.no_session"] == 1
    assert r.posted == [] and len(r.gateway.sessions) == 1  # nothing reached the bat; the player is still in
    player.send_input([2.0, 0, 0, 0, 0, 0], tick=3)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1)
    version = r.client()
    version.send_raw(bytes(bytearray(wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="old",
                                                 token=bytes(16)))[:4]) + (1).to_bytes(2, "little")
                     + wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="old", token=bytes(16))[6:])
    reject = r.until(version, lambda m: m.kind == Kind.REJECT)
    assert reject["reason"] == RejectReason.VERSION


def test_a_malformed_hello_is_rejected_bad_request_with_the_decoders_reason(rig):
    r = rig()
    hello = wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="ann", token=bytes(16))
    bad_name = bytearray(hello)
    bad_name[26:30] = b"\x1b[2J"[:4]  # a terminal escape in the name
    watcher_with_slot = bytearray(wire.encode(Kind.HELLO, role=Role.SPECTATOR, slot=Slot.NONE, name="sp",
                                              token=bytes(16)))
    watcher_with_slot[25] = int(Slot.A)
    cases = {"too_short": hello[:40], "too_long": hello + b"\0", "bad_text": bytes(bad_name),
             "out_of_range": bytes(watcher_with_slot)}
    for reason, data in cases.items():
        client = r.client()
        client.send_raw(data)
        reject = r.until(client, lambda m: m.kind == Kind.REJECT)
        assert reject["reason"] == RejectReason.BAD_REQUEST and reject["detail"], reason
        assert r.gateway.stats()[f"dropped.{reason}"] == 1
    assert "hello.slot" in reject["detail"]  # the decoder's own words: what was wrong
    assert r.gateway.counts["rejected.bad_request"] == len(cases) and r.gateway.sessions == {}
    stranger = r.client()
    stranger.send_raw(bytes(_good_input()))  # not a hello: no reject (a goodbye, see below)
    assert r.until(stranger, lambda m: True).kind == Kind.GOODBYE


def test_target_mode_is_refused_counted_and_kicks_like_any_bad_message(rig):
    from processes.network.wire import MAX_BAD

    r = rig()
    player = r.client()
    r.join(player)
    for _ in range(MAX_BAD):
        player.send(Kind.INPUT, slot=Slot.A, mode=wire.InputMode.TARGET, force=[0, 0, 0], torque=[0, 0, 0],
                    target_pos=[-1.6, 0.0, 0.15], target_quat=[1.0, 0, 0, 0])
    goodbye = r.until(player, lambda m: m.kind == Kind.GOODBYE)
    assert goodbye["reason"] == GoodbyeReason.KICKED
    assert r.gateway.counts["refused.target_mode"] == MAX_BAD and r.gateway.counts["kicked"] == 1
    assert r.posted == []  # no target reached the bat


def test_a_force_input_with_target_fields_is_dropped_and_counted_as_a_bad_message(rig):
    r = rig()
    player = r.client()
    r.join(player)
    data = bytearray(wire.encode(Kind.INPUT, slot=Slot.A, mode=wire.InputMode.FORCE, force=[1.0, 0, 0],
                                 torque=[0, 0, 0], target_pos=[0, 0, 0], target_quat=[0, 0, 0, 0]))
    at = wire.SPECS[Kind.INPUT].dtype.fields["target_pos"][1]
    data[at:at + 8] = np.float64(0.5).tobytes()  # target_pos.x, which force mode keeps zero
    player.send_raw(bytes(data))
    r.settle(lambda: r.gateway.drops.by_reason["out_of_range"] == 1)
    assert r.posted == [] and [s.bad for s in r.gateway.sessions.values()] == [1]  # not applied; one bad
    assert player.recv(100) is None  # and not answered
