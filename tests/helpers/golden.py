"""Fourteen wire messages, one of every kind or more, with fixed field values and their exact bytes:
what the wire's tests decode and encode, and the page's decoder reads (tests/processes/network/web)."""
import math

import numpy as np

from engine.play.rules import REASONS, Phase, Reason
from processes.network import wire
from processes.network.wire import EventKind, GoodbyeReason, InputMode, Kind, RejectReason, Role, Slot

TOKEN = bytes(range(0xA0, 0xB0))
DIGEST = bytes.fromhex("5ce7e1a2b3c4d5f6")
SCENE_TEXT = 'name = "Zoë"\ndt = 0.001\n'.encode()  # the second part of a scene cut after 4000 bytes
R = math.sqrt(0.5)  # a 90-degree turn about y: (R, 0, +-R, 0), norm 1 to the last bit or two

# Fourteen predefined messages: fixed field values and their exact bytes. The hex is frozen on purpose
# (computed once, pasted here): a change of layout, order, size or byte order fails this test.
# The second message of an 85 x 8 net: knots 640..679, the first two moved, the rest at rest.
NET_OFFSET = np.zeros((wire.NET_CHUNK_KNOTS, 3), np.int16)
NET_OFFSET[0], NET_OFFSET[1] = (1500, -2, 32767), (-32767, 0, 7)
GOLDEN_FIELDS = {
    "hello_player": (Kind.HELLO, dict(seq=1, tick=0, role=Role.PLAYER, slot=Slot.NONE, name="Ada", token=bytes(16))),
    "hello_rejoin_b": (Kind.HELLO, dict(seq=7, tick=0, role=Role.PLAYER, slot=Slot.B, name="Zoë 卓球", token=TOKEN)),
    "welcome_a": (Kind.WELCOME, dict(seq=1, tick=1234, slot=Slot.A, best_of=5, snapshot_hz=60, heartbeat_ms=500,
                                     timeout_ms=3000, dt=0.001, token=TOKEN, scene="match", name_a="Ada",
                                     name_b="AI (pro)", feed_port=0, scene_digest=DIGEST)),
    "welcome_spectator": (Kind.WELCOME, dict(seq=1, tick=1234, slot=Slot.NONE, best_of=5, snapshot_hz=120,
                                             heartbeat_ms=500, timeout_ms=5000, dt=0.001, token=bytes(16),
                                             scene="match", name_a="Ada", name_b="", feed_port=5556,
                                             scene_digest=DIGEST)),
    "reject_full": (Kind.REJECT, dict(seq=2, tick=99, reason=RejectReason.FULL, detail="both seats are taken")),
    "input_force": (Kind.INPUT, dict(seq=42, tick=2000, slot=Slot.A, mode=InputMode.FORCE, force=(12.5, -3.0, 9.81),
                                     torque=(0.0, 0.25, -1.5), target_pos=(0, 0, 0), target_quat=(0, 0, 0, 0))),
    "input_target": (Kind.INPUT, dict(seq=43, tick=2010, slot=Slot.B, mode=InputMode.TARGET, force=(0, 0, 0),
                                      torque=(0, 0, 0), target_pos=(1.6, -0.2, 0.15), target_quat=(R, 0.0, -R, 0.0))),
    "snapshot": (Kind.SNAPSHOT, dict(seq=1000, tick=16667, ball_pos=(-0.5, 0.125, 0.3), ball_vel=(6.0, -0.5, 1.25),
                                     ball_spin=(0.0, -150.0, 20.0), bat_pos=((-1.6, 0.1, 0.2), (1.55, -0.3, 0.25)),
                                     bat_quat=((R, 0.0, R, 0.0), (R, 0.0, -R, 0.0)),
                                     bat_vel=((2.0, 0.0, 0.5), (-0.25, 0.0, 0.0)),
                                     bat_ang_vel=((0.0, 1.0, 0.0), (0.0, 0.0, -2.0)), input_seq=(42, 0), rally=17,
                                     score=(7, 9), games_won=(1, 2), phase=Phase.STRUCK, server=1, striker=0,
                                     winner=-1, realtime_factor=0.75)),
    "event_point": (Kind.EVENT, dict(seq=1001, tick=16900, event=EventKind.POINT, winner=1,
                                     reason=REASONS.index(Reason.OUT_LONG), game=3, score=(7, 10), games_won=(1, 2),
                                     shots=6, rally=17)),
    "heartbeat": (Kind.HEARTBEAT, dict(seq=77, tick=17000, ack=1001)),
    "goodbye_shutdown": (Kind.GOODBYE, dict(seq=1200, tick=20000, reason=GoodbyeReason.SHUTDOWN)),
    "net": (Kind.NET, dict(seq=1300, tick=20001, cols=85, rows=8, first=640, count=40, asleep=0, width=1.83,
                           height=0.1525, offset=NET_OFFSET)),
    "scene_request": (Kind.SCENE_REQUEST, dict(seq=3, tick=1240, digest=DIGEST)),
    "scene_part": (Kind.SCENE_PART, dict(seq=2, tick=1241, digest=DIGEST, part=1, parts=2, size=len(SCENE_TEXT),
                                         text=SCENE_TEXT.ljust(wire.SCENE_CHUNK, b"\0"))),
}

GOLDEN_HEX = {
    "hello_player": (
        "50504e470500010001000000000000000000000000000000010041646100000000000000000000000000000000000000"
        "0000000000000000000000000000000000000000000000000000"
    ),
    "hello_rejoin_b": (
        "50504e47050001000700000000000000000000000000000001025a6fc3ab20e58d93e790830000000000000000000000"
        "00000000000000000000a0a1a2a3a4a5a6a7a8a9aaabacadaeaf"
    ),
    "welcome_a": (
        "50504e47050002000100000000000000d20400000000000001053c00f4010000b80b0000fca9f1d24d62503fa0a1a2a3"
        "a4a5a6a7a8a9aaabacadaeaf6d6174636800000000000000000000000000000000000000000000000000000041646100"
        "000000000000000000000000000000000000000000000000000000004149202870726f29000000000000000000000000"
        "00000000000000000000000000005ce7e1a2b3c4d5f6"
    ),
    "welcome_spectator": (
        "50504e47050002000100000000000000d20400000000000000057800f401000088130000fca9f1d24d62503f00000000"
        "0000000000000000000000006d6174636800000000000000000000000000000000000000000000000000000041646100"
        "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
        "000000000000000000000000b4155ce7e1a2b3c4d5f6"
    ),
    "reject_full": (
        "50504e47050003000200000000000000630000000000000001626f7468207365617473206172652074616b656e000000"
        "0000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    ),
    "input_force": (
        "50504e47050004002a00000000000000d0070000000000000101000000000000294000000000000008c01f85eb51b89e"
        "23400000000000000000000000000000d03f000000000000f8bf00000000000000000000000000000000000000000000"
        "00000000000000000000000000000000000000000000000000000000000000000000"
    ),
    "input_target": (
        "50504e47050004002b00000000000000da07000000000000020200000000000000000000000000000000000000000000"
        "00000000000000000000000000000000000000000000000000009a9999999999f93f9a9999999999c9bf333333333333"
        "c33fcd3b7f669ea0e63f0000000000000000cd3b7f669ea0e6bf0000000000000000"
    ),
    "snapshot": (
        "50504e4705000500e8030000000000001b41000000000000000000000000e0bf000000000000c03f333333333333d33f"
        "0000000000001840000000000000e0bf000000000000f43f00000000000000000000000000c062c00000000000003440"
        "9a9999999999f9bf9a9999999999b93f9a9999999999c93fcdccccccccccf83f333333333333d3bf000000000000d03f"
        "cd3b7f669ea0e63f0000000000000000cd3b7f669ea0e63f0000000000000000cd3b7f669ea0e63f0000000000000000"
        "cd3b7f669ea0e6bf000000000000000000000000000000400000000000000000000000000000e03f000000000000d0bf"
        "000000000000000000000000000000000000000000000000000000000000f03f00000000000000000000000000000000"
        "000000000000000000000000000000c02a00000000000000000000000000000011000000070009000102030100ff"
        "0000403f"
    ),
    "event_point": (
        "50504e4705000600e90300000000000004420000000000000101040307000a000102060011000000"
    ),
    "heartbeat": (
        "50504e47050007004d000000000000006842000000000000e903000000000000"
    ),
    "goodbye_shutdown": (
        "50504e4705000800b004000000000000204e00000000000002"
    ),
    "net": (  # 63 bytes, then zero: the offsets of the 38 knots at rest and the 600 rows past count
        "50504e47050009001405000000000000214e000000000000550008008002000028000048e17a14ae47fd3f85eb51b81e"
        "85c33fdc05feffff7f018000000700" + "00" * (3891 - 63)
    ),
    "scene_request": (
        "50504e4705000a000300000000000000d8040000000000005ce7e1a2b3c4d5f6"
    ),
    "scene_part": (  # 61 bytes, then zero: the text's 25 bytes end there
        "50504e4705000b000200000000000000d9040000000000005ce7e1a2b3c4d5f6010219006e616d65203d20225a6fc3ab22"
        "0a6474203d20302e3030310a" + "00" * (4036 - 61)
    ),
}
GOLDEN = {name: bytes.fromhex(text) for name, text in GOLDEN_HEX.items()}


def patched(golden, /, **changes):
    """The golden message `golden` with some fields changed, built by hand (bypassing encode's checks)."""
    kind, _ = GOLDEN_FIELDS[golden]
    rec = np.frombuffer(GOLDEN[golden], wire.SPECS[kind].dtype).copy()
    for field, value in changes.items():
        rec[0][field] = value
    return rec.tobytes()
