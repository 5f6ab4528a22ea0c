"""The wire protocol: golden bytes, exact layouts, and a decoder that refuses every bad message
with a counted WireError and never anything else."""
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.rules import REASONS, Phase, Reason
from processes.network import wire
from processes.network.wire import (
    BadEnum, BadFlags, BadMagic, BadText, BadVersion, DropCounter, EventKind, GoodbyeReason, InputMode, Kind,
    NonFinite, OutOfRange, RejectReason, Role, Slot, TooLong, TooShort, UnknownType, WireError, decode, encode,
)
from tests.waits import DEADLINE_S

TOKEN = bytes(range(0xA0, 0xB0))
R = math.sqrt(0.5)  # a 90-degree turn about y: (R, 0, +-R, 0), norm 1 to the last bit or two

# Twelve predefined messages: fixed field values and their exact bytes. The hex is frozen on purpose
# (computed once, pasted here): a change of layout, order, size or byte order fails this test.
# The second message of an 85 x 8 net: knots 640..679, the first two moved, the rest at rest.
NET_OFFSET = np.zeros((wire.NET_CHUNK_KNOTS, 3), np.int16)
NET_OFFSET[0], NET_OFFSET[1] = (1500, -2, 32767), (-32767, 0, 7)
GOLDEN_FIELDS = {
    "hello_player": (Kind.HELLO, dict(seq=1, tick=0, role=Role.PLAYER, slot=Slot.NONE, name="Ada", token=bytes(16))),
    "hello_rejoin_b": (Kind.HELLO, dict(seq=7, tick=0, role=Role.PLAYER, slot=Slot.B, name="Zoë 卓球", token=TOKEN)),
    "welcome_a": (Kind.WELCOME, dict(seq=1, tick=1234, slot=Slot.A, best_of=5, snapshot_hz=60, heartbeat_ms=500,
                                     timeout_ms=3000, dt=0.001, token=TOKEN, scene="match", name_a="Ada",
                                     name_b="AI (pro)", feed_port=0)),
    "welcome_spectator": (Kind.WELCOME, dict(seq=1, tick=1234, slot=Slot.NONE, best_of=5, snapshot_hz=120,
                                             heartbeat_ms=500, timeout_ms=5000, dt=0.001, token=bytes(16),
                                             scene="match", name_a="Ada", name_b="", feed_port=5556)),
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
}

GOLDEN_HEX = {
    "hello_player": (
        "50504e470400010001000000000000000000000000000000010041646100000000000000000000000000000000000000"
        "0000000000000000000000000000000000000000000000000000"
    ),
    "hello_rejoin_b": (
        "50504e47040001000700000000000000000000000000000001025a6fc3ab20e58d93e790830000000000000000000000"
        "00000000000000000000a0a1a2a3a4a5a6a7a8a9aaabacadaeaf"
    ),
    "welcome_a": (
        "50504e47040002000100000000000000d20400000000000001053c00f4010000b80b0000fca9f1d24d62503fa0a1a2a3"
        "a4a5a6a7a8a9aaabacadaeaf6d6174636800000000000000000000000000000000000000000000000000000041646100"
        "000000000000000000000000000000000000000000000000000000004149202870726f29000000000000000000000000"
        "0000000000000000000000000000"
    ),
    "welcome_spectator": (
        "50504e47040002000100000000000000d20400000000000000057800f401000088130000fca9f1d24d62503f00000000"
        "0000000000000000000000006d6174636800000000000000000000000000000000000000000000000000000041646100"
        "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
        "000000000000000000000000b415"
    ),
    "reject_full": (
        "50504e47040003000200000000000000630000000000000001626f7468207365617473206172652074616b656e000000"
        "0000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    ),
    "input_force": (
        "50504e47040004002a00000000000000d0070000000000000101000000000000294000000000000008c01f85eb51b89e"
        "23400000000000000000000000000000d03f000000000000f8bf00000000000000000000000000000000000000000000"
        "00000000000000000000000000000000000000000000000000000000000000000000"
    ),
    "input_target": (
        "50504e47040004002b00000000000000da07000000000000020200000000000000000000000000000000000000000000"
        "00000000000000000000000000000000000000000000000000009a9999999999f93f9a9999999999c9bf333333333333"
        "c33fcd3b7f669ea0e63f0000000000000000cd3b7f669ea0e6bf0000000000000000"
    ),
    "snapshot": (
        "50504e4704000500e8030000000000001b41000000000000000000000000e0bf000000000000c03f333333333333d33f"
        "0000000000001840000000000000e0bf000000000000f43f00000000000000000000000000c062c00000000000003440"
        "9a9999999999f9bf9a9999999999b93f9a9999999999c93fcdccccccccccf83f333333333333d3bf000000000000d03f"
        "cd3b7f669ea0e63f0000000000000000cd3b7f669ea0e63f0000000000000000cd3b7f669ea0e63f0000000000000000"
        "cd3b7f669ea0e6bf000000000000000000000000000000400000000000000000000000000000e03f000000000000d0bf"
        "000000000000000000000000000000000000000000000000000000000000f03f00000000000000000000000000000000"
        "000000000000000000000000000000c02a00000000000000000000000000000011000000070009000102030100ff"
        "0000403f"
    ),
    "event_point": (
        "50504e4704000600e90300000000000004420000000000000101040307000a000102060011000000"
    ),
    "heartbeat": (
        "50504e47040007004d000000000000006842000000000000e903000000000000"
    ),
    "goodbye_shutdown": (
        "50504e4704000800b004000000000000204e00000000000002"
    ),
    "net": (  # 63 bytes, then zero: the offsets of the 38 knots at rest and the 600 rows past count
        "50504e47040009001405000000000000214e000000000000550008008002000028000048e17a14ae47fd3f85eb51b81e"
        "85c33fdc05feffff7f018000000700" + "00" * (3891 - 63)
    ),
}
GOLDEN = {name: bytes.fromhex(text) for name, text in GOLDEN_HEX.items()}
EXPECTED_SIZES = {Kind.HELLO: 74, Kind.WELCOME: 158, Kind.REJECT: 89, Kind.INPUT: 130, Kind.SNAPSHOT: 338,
                  Kind.EVENT: 40, Kind.HEARTBEAT: 32, Kind.GOODBYE: 25, Kind.NET: 3891}


def _reencode(message):
    return encode(message.kind, seq=message.seq, tick=message.tick, flags=message.flags, **message.fields)


def _patched(golden, /, **changes):
    """The golden message `golden` with some fields changed, built by hand (bypassing encode's checks)."""
    kind, _ = GOLDEN_FIELDS[golden]
    rec = np.frombuffer(GOLDEN[golden], wire.SPECS[kind].dtype).copy()
    for field, value in changes.items():
        rec[0][field] = value
    return rec.tobytes()


# --- layouts -----------------------------------------------------------------------------------------------
def test_twelve_golden_messages_cover_every_type():
    assert len(GOLDEN) == 12
    assert {kind for kind, _ in GOLDEN_FIELDS.values()} == set(Kind)


@pytest.mark.parametrize("kind", list(Kind))
def test_layout_is_packed_little_endian_and_sized_as_documented(kind):
    dtype = wire.SPECS[kind].dtype
    assert dtype.itemsize == EXPECTED_SIZES[kind] == wire.SIZES[kind]
    assert dtype.itemsize == sum(dtype.fields[name][0].itemsize for name in dtype.names)  # no padding
    for name in dtype.names:
        assert dtype.fields[name][0].base.str[0] in "<|", name  # explicit little-endian or single byte
    assert dtype.names[:6] == wire.HEADER_DTYPE.names and wire.HEADER_SIZE == 24


@pytest.mark.parametrize("kind", list(Kind))
def test_docstring_layout_lists_every_field_at_its_offset(kind):
    spec = wire.SPECS[kind]
    doc = spec.__doc__
    assert f"Layout, {spec.dtype.itemsize} bytes:" in doc
    rows = re.findall(r"^\s+(\d+)\s+(\d+)\s+(\w+)\s", doc.split("Layout")[1], re.MULTILINE)
    listed = {name: (int(offset), int(size)) for offset, size, name in rows}
    assert listed.pop("header") == (0, wire.HEADER_SIZE)
    actual = {name: (spec.dtype.fields[name][1], spec.dtype.fields[name][0].itemsize) for name in spec.names}
    assert listed == actual


def test_module_docstring_header_table_matches_the_header_dtype():
    rows = re.findall(r"^\s+(\d+)\s+(\d+)\s+(\w+)\s", wire.__doc__.split("Text fields")[0], re.MULTILINE)
    listed = {name: (int(offset), int(size)) for offset, size, name in rows}
    dtype = wire.HEADER_DTYPE
    assert listed == {name: (dtype.fields[name][1], dtype.fields[name][0].itemsize) for name in dtype.names}


def test_magic_and_version_are_the_first_six_bytes():
    for data in GOLDEN.values():
        assert data[:4] == b"PPNG" and data[4:6] == wire.PROTOCOL_VERSION.to_bytes(2, "little")


# --- golden messages ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(GOLDEN_FIELDS))
def test_golden_message_bytes(name):
    kind, fields = GOLDEN_FIELDS[name]
    assert encode(kind, **fields) == GOLDEN[name]
    assert encode(kind.name.lower(), **fields) == GOLDEN[name]  # by name too


@pytest.mark.parametrize("name", list(GOLDEN_FIELDS))
def test_golden_message_round_trip(name):
    kind, fields = GOLDEN_FIELDS[name]
    message = decode(GOLDEN[name])
    assert (message.kind, message.seq, message.tick, message.flags) == (kind, fields["seq"], fields["tick"], 0)
    for field, value in fields.items():
        if field in ("seq", "tick"):
            continue
        if isinstance(message[field], np.ndarray):
            np.testing.assert_array_equal(message[field], value)  # float64 on the wire: exact
        else:
            assert message[field] == value, field
    assert _reencode(message) == GOLDEN[name]
    assert json.loads(json.dumps(message.to_dict(), ensure_ascii=False))["kind"] == name.split("_")[0]


def test_an_events_reason_and_a_snapshots_phase_are_named_in_its_dict():
    event = decode(GOLDEN["event_point"]).to_dict()
    assert event["reason"] == REASONS.index(Reason.OUT_LONG) and event["reason_name"] == "out_long"
    assert decode(GOLDEN["snapshot"]).to_dict()["phase"] == "struck"


def test_spectator_welcome_and_match_event_round_trip():
    _, welcome = GOLDEN_FIELDS["welcome_a"]
    spectator = {**welcome, "slot": Slot.NONE, "token": bytes(16), "name_b": ""}
    message = decode(encode(Kind.WELCOME, **spectator))
    assert message["slot"] is Slot.NONE and message["token"] == bytes(16) and message["name_b"] == ""
    with pytest.raises(OutOfRange):
        encode(Kind.WELCOME, **{**spectator, "token": TOKEN})  # a spectator has nothing to rejoin
    _, feed = GOLDEN_FIELDS["welcome_spectator"]
    assert decode(GOLDEN["welcome_spectator"])["feed_port"] == 5556
    with pytest.raises(OutOfRange, match="feed_port"):
        encode(Kind.WELCOME, **{**welcome, "feed_port": 5556})  # a player's snapshots come on its session
    _, point = GOLDEN_FIELDS["event_point"]
    end = {**point, "event": EventKind.MATCH, "score": (9, 11), "games_won": (1, 3)}
    assert decode(encode(Kind.EVENT, **end))["event"] is EventKind.MATCH


def test_decoded_fields_are_typed_and_read_only():
    hello = decode(GOLDEN["hello_rejoin_b"])
    assert hello["role"] is Role.PLAYER and hello["slot"] is Slot.B
    assert hello["name"] == "Zoë 卓球" and hello["token"] == TOKEN
    snapshot = decode(GOLDEN["snapshot"])
    assert snapshot["phase"] is Phase.STRUCK and snapshot["winner"] == -1
    assert snapshot["bat_quat"].shape == (2, 4) and snapshot["bat_quat"].dtype == np.float64
    with pytest.raises(ValueError):
        snapshot["ball_pos"][0] = 1.0  # a view of the decoder's private copy, frozen


def test_decode_copies_the_callers_buffer():
    buf = bytearray(GOLDEN["snapshot"])
    message = decode(memoryview(buf))
    buf[24:48] = bytes(24)  # the caller reuses its receive buffer
    np.testing.assert_array_equal(message["ball_pos"], (-0.5, 0.125, 0.3))


# --- every malformed-message class --------------------------------------------------------------------------
def _with_header(name, **changes):
    data = bytearray(GOLDEN[name])
    header = np.frombuffer(bytes(data[:24]), wire.HEADER_DTYPE).copy()
    for field, value in changes.items():
        header[0][field] = value
    data[:24] = header.tobytes()
    return bytes(data)


BAD = {
    "empty": (b"", TooShort),
    "header_cut": (GOLDEN["heartbeat"][:23], TooShort),
    "body_cut_by_one": (GOLDEN["snapshot"][:-1], TooShort),
    "one_byte_extra": (GOLDEN["snapshot"] + b"\0", TooLong),
    "two_messages_glued": (GOLDEN["heartbeat"] * 2, TooLong),
    "magic": (b"PPNH" + GOLDEN["heartbeat"][4:], BadMagic),
    "version_0": (_with_header("heartbeat", version=0), BadVersion),
    "version_1": (_with_header("heartbeat", version=1), BadVersion),  # the first layout, before the feed
    "version_2": (_with_header("heartbeat", version=2), BadVersion),  # before the net message
    "version_3": (_with_header("heartbeat", version=3), BadVersion),  # before snapshot.realtime_factor
    "version_5": (_with_header("heartbeat", version=5), BadVersion),
    "type_0": (_with_header("heartbeat", kind=0), UnknownType),
    "type_10": (_with_header("heartbeat", kind=10), UnknownType),
    "type_255": (_with_header("heartbeat", kind=255), UnknownType),
    "flags": (_with_header("heartbeat", flags=0x80), BadFlags),
    "negative_tick": (_with_header("heartbeat", tick=-1), OutOfRange),
    "nan_force": (_patched("input_force", force=(math.nan, 0, 0)), NonFinite),
    "inf_torque": (_patched("input_force", torque=(0, -math.inf, 0)), NonFinite),
    "nan_ball_pos": (_patched("snapshot", ball_pos=(0, 0, math.nan)), NonFinite),
    "nan_in_unused_target": (_patched("input_force", target_quat=(math.nan, 0, 0, 0)), NonFinite),
    "inf_dt": (_patched("welcome_a", dt=math.inf), NonFinite),
    "force_501_N": (_patched("input_force", force=(300.0, 400.0, 10.0)), OutOfRange),
    "torque_51_N_m": (_patched("input_force", torque=(0.0, 0.0, 51.0)), OutOfRange),
    "target_far_away": (_patched("input_target", target_pos=(8.5, 0, 0)), OutOfRange),
    "target_quat_not_unit": (_patched("input_target", target_quat=(1.0, 0, 0, 2e-3)), OutOfRange),
    "force_in_target_mode": (_patched("input_target", force=(1.0, 0, 0)), OutOfRange),
    "input_for_no_slot": (_patched("input_force", slot=0), OutOfRange),
    "target_in_force_mode": (_patched("input_force", target_pos=(0.0, 0.1, 0.0)), OutOfRange),
    "hello_tick_not_0": (_with_header("hello_player", tick=7), OutOfRange),
    "ball_far_away": (_patched("snapshot", ball_pos=(0, 100.0, 0)), OutOfRange),
    "ball_too_fast": (_patched("snapshot", ball_vel=(0, 0, 101.0)), OutOfRange),
    "ball_spin_wild": (_patched("snapshot", ball_spin=(2001.0, 0, 0)), OutOfRange),
    "bat_quat_zero": (_patched("snapshot", bat_quat=((0, 0, 0, 0), (1, 0, 0, 0))), OutOfRange),
    "games_won_6": (_patched("snapshot", games_won=(6, 0)), OutOfRange),
    "server_2": (_patched("snapshot", server=2), OutOfRange),
    "winner_minus_2": (_patched("snapshot", winner=-2), OutOfRange),
    "best_of_even": (_patched("welcome_a", best_of=4), OutOfRange),
    "dt_zero": (_patched("welcome_a", dt=0.0), OutOfRange),
    "timeout_below_heartbeat": (_patched("welcome_a", timeout_ms=100), OutOfRange),
    "player_without_token": (_patched("welcome_a", token=np.zeros(16, np.uint8)), OutOfRange),
    "spectator_asks_a_slot": (_patched("hello_player", role=Role.SPECTATOR, slot=Slot.A), OutOfRange),
    "let_with_winner": (_patched("event_point", reason=REASONS.index(Reason.LET)), OutOfRange),
    "role_0": (_patched("hello_player", role=0), BadEnum),
    "role_3": (_patched("hello_player", role=3), BadEnum),
    "slot_3": (_patched("welcome_a", slot=3), BadEnum),
    "input_mode_0": (_patched("input_force", mode=0), BadEnum),
    "phase_6": (_patched("snapshot", phase=6), BadEnum),
    "reject_reason_0": (_patched("reject_full", reason=0), BadEnum),
    "event_kind_4": (_patched("event_point", event=4), BadEnum),
    "rules_reason_past_the_end": (_patched("event_point", reason=len(REASONS)), BadEnum),
    "goodbye_reason_99": (_patched("goodbye_shutdown", reason=99), BadEnum),
    "net_cut_by_one": (GOLDEN["net"][:-1], TooShort),
    "net_one_byte_extra": (GOLDEN["net"] + b"\0", TooLong),
    "net_offset_minus_32768": (_patched("net", offset=np.where(np.arange(640)[:, None] == 3, -32768, NET_OFFSET)),
                               OutOfRange),
    "net_offset_past_count": (_patched("net", offset=np.where(np.arange(640)[:, None] == 40, 1, NET_OFFSET)),
                              OutOfRange),
    "net_count_0": (_patched("net", count=0), OutOfRange),
    "net_count_641": (_patched("net", count=641), OutOfRange),
    "net_past_the_last_knot": (_patched("net", first=641), OutOfRange),
    "net_one_column": (_patched("net", cols=1, first=0), OutOfRange),
    "net_asleep_2": (_patched("net", asleep=2), OutOfRange),
    "net_width_zero": (_patched("net", width=0.0), OutOfRange),
    "net_height_9": (_patched("net", height=9.0), OutOfRange),
    "net_nan_width": (_patched("net", width=math.nan), NonFinite),
}


def _name_bytes(raw: bytes) -> np.ndarray:
    return np.frombuffer(raw.ljust(wire.NAME_SIZE, b"\0"), np.uint8)


BAD.update({
    "name_empty": (_patched("hello_player", name=_name_bytes(b"")), BadText),
    "name_not_utf8": (_patched("hello_player", name=_name_bytes(b"Ad\xff")), BadText),
    "name_cut_mid_character": (_patched("hello_player", name=_name_bytes("卓".encode()[:2])), BadText),
    "name_escape_sequence": (_patched("hello_player", name=_name_bytes(b"\x1b[2JAda")), BadText),
    "name_bidi_override": (_patched("hello_player", name=_name_bytes("Ada\u202e".encode())), BadText),
    "name_nul_inside": (_patched("hello_player", name=_name_bytes(b"Ad\0a")), BadText),
    "name_trailing_space": (_patched("hello_player", name=_name_bytes(b"Ada ")), BadText),
    "name_full_32_bytes_of_newline": (_patched("hello_player", name=_name_bytes(b"\n" * 32)), BadText),
    "scene_empty": (_patched("welcome_a", scene=_name_bytes(b"")), BadText),
})


@pytest.mark.parametrize("case", list(BAD))
def test_bad_message_raises_its_wire_error(case):
    data, error = BAD[case]
    with pytest.raises(error) as raised:
        decode(data)
    assert raised.value.reason in wire.REASON_CODES


def test_every_reason_code_has_a_bad_message():
    assert {error.reason for _, error in BAD.values()} == set(wire.REASON_CODES)


def test_bad_version_tells_the_version_seen():
    with pytest.raises(BadVersion) as raised:
        decode(_with_header("goodbye_shutdown", version=7))
    assert raised.value.version == 7


def test_quaternion_tolerance_is_1e_6():
    q = np.array([R, 0.0, -R, 0.0])
    assert decode(_patched("input_target", target_quat=q * (1 + 0.9e-6)))  # |q| - 1 = 0.9e-6: accepted
    with pytest.raises(OutOfRange):
        decode(_patched("input_target", target_quat=q * (1 + 1.1e-6)))  # 1.1e-6: refused


def test_force_limit_is_on_the_norm_500_N():
    assert decode(_patched("input_force", force=(300.0, 400.0, 0.0)))  # |F| = 500 N exactly: accepted
    with pytest.raises(OutOfRange):
        decode(_patched("input_force", force=(300.0, 400.0, 1e-3)))  # 500.000001 N


def test_a_let_is_a_point_without_winner():
    let = _patched("event_point", reason=REASONS.index(Reason.LET), winner=-1)
    assert decode(let)["winner"] == -1
    with pytest.raises(OutOfRange):
        decode(_patched("event_point", winner=-1))  # out_long needs a winner


# --- the encoder refuses what the decoder would -------------------------------------------------------------
def test_encode_refuses_values_the_peer_would_drop():
    _, fields = GOLDEN_FIELDS["input_force"]
    with pytest.raises(OutOfRange):
        encode(Kind.INPUT, **{**fields, "force": (0.0, 0.0, 500.5)})
    with pytest.raises(NonFinite):
        encode(Kind.INPUT, **{**fields, "torque": (0.0, math.nan, 0.0)})
    with pytest.raises(OutOfRange):
        encode(Kind.INPUT, **{**fields, "seq": -1})
    with pytest.raises(OutOfRange):
        encode(Kind.INPUT, **{**fields, "seq": 2**64})
    with pytest.raises(OutOfRange):
        encode(Kind.INPUT, **{**fields, "tick": -5})
    with pytest.raises(BadFlags):
        encode(Kind.INPUT, flags=1, **fields)
    _, hello = GOLDEN_FIELDS["hello_player"]
    with pytest.raises(BadText):
        encode(Kind.HELLO, **{**hello, "name": "x" * 33})  # 33 bytes: would be cut, so refused
    with pytest.raises(BadText):
        encode(Kind.HELLO, **{**hello, "name": "é" * 17})  # 17 characters, 34 bytes
    assert decode(encode(Kind.HELLO, **{**hello, "name": "é" * 16}))["name"] == "é" * 16  # exactly 32 bytes
    with pytest.raises(BadText):
        encode(Kind.HELLO, **{**hello, "name": "Ada\n"})
    with pytest.raises(UnknownType):
        encode("ping", seq=1)


def test_encode_programming_errors_are_type_errors():
    _, fields = GOLDEN_FIELDS["heartbeat"]
    with pytest.raises(TypeError, match="unknown fields \\['nonce'\\]"):
        encode(Kind.HEARTBEAT, nonce=1, **fields)
    with pytest.raises(TypeError, match="missing fields \\['ack'\\]"):
        encode(Kind.HEARTBEAT, seq=1)
    _, fields = GOLDEN_FIELDS["input_force"]
    with pytest.raises(TypeError):
        encode(Kind.INPUT, **{**fields, "force": (1.0, 2.0)})
    _, hello = GOLDEN_FIELDS["hello_player"]
    with pytest.raises(TypeError):
        encode(Kind.HELLO, **{**hello, "token": b"short"})


# --- no other exception, whatever the bytes (hypothesis) -----------------------------------------------------
def _decode_or_wire_error(data: bytes):
    """decode, allowing only WireError; an accepted message must re-encode to the same bytes
    (every accepted message has exactly one encoding)."""
    try:
        with np.errstate(all="raise"):  # a gateway with strict floating point must not see FloatingPointError
            message = decode(data)
    except WireError as err:
        assert err.reason in wire.REASON_CODES
        return None
    assert _reencode(message) == data
    return message


@settings(deadline=None, max_examples=2000)
@given(st.binary(max_size=400))
def test_random_bytes_only_raise_wire_errors(data):
    _decode_or_wire_error(data)


@settings(deadline=None, max_examples=2000)
@given(st.sampled_from(list(Kind)), st.data())
def test_random_bodies_behind_a_valid_header_only_raise_wire_errors(kind, data):
    header = np.zeros(1, wire.HEADER_DTYPE)
    header["magic"], header["version"], header["kind"] = wire.MAGIC, wire.PROTOCOL_VERSION, kind
    header["tick"] = data.draw(st.integers(0, 2**40))
    size = wire.SIZES[kind] - wire.HEADER_SIZE
    body = data.draw(st.binary(min_size=max(0, size - 2), max_size=size + 2))
    _decode_or_wire_error(header.tobytes() + body)


@st.composite
def _mutated(draw):
    data = bytearray(GOLDEN[draw(st.sampled_from(sorted(GOLDEN)))])
    for _ in range(draw(st.integers(1, 4))):
        what = draw(st.sampled_from(["set", "flip", "cut", "grow", "float"]))
        if what == "set" and data:
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        elif what == "flip" and data:
            data[draw(st.integers(0, len(data) - 1))] ^= 1 << draw(st.integers(0, 7))
        elif what == "cut" and data:
            del data[draw(st.integers(0, len(data) - 1)):]
        elif what == "grow":
            data += draw(st.binary(min_size=1, max_size=8))
        elif what == "float" and len(data) >= 32:  # write a whole float64 somewhere: NaN, inf, huge, tiny
            at = draw(st.integers(24, len(data) - 8))
            data[at:at + 8] = np.float64(draw(st.floats(allow_nan=True, allow_infinity=True))).tobytes()
    return bytes(data)


@settings(deadline=None, max_examples=3000, suppress_health_check=[HealthCheck.too_slow])
@given(_mutated())
def test_mutated_golden_messages_only_raise_wire_errors(data):
    _decode_or_wire_error(data)


_force = st.floats(-280.0, 280.0)  # each component: |F| <= 280 * sqrt(3) = 485 N < 500 N
_torque = st.floats(-28.0, 28.0)  # |torque| <= 48.5 N m < 50 N m


@settings(deadline=None, max_examples=500)
@given(st.integers(0, 2**64 - 1), st.integers(0, 2**63 - 1), st.sampled_from([Slot.A, Slot.B]),
       st.tuples(_force, _force, _force), st.tuples(_torque, _torque, _torque))
def test_valid_force_inputs_round_trip_exactly(seq, tick, slot, force, torque):
    data = encode(Kind.INPUT, seq=seq, tick=tick, slot=slot, mode=InputMode.FORCE, force=force, torque=torque,
                  target_pos=(0, 0, 0), target_quat=(0, 0, 0, 0))
    message = decode(data)
    assert (message.seq, message.tick, message["slot"]) == (seq, tick, slot)
    np.testing.assert_array_equal(message["force"], force)  # float64 both ways: bit-exact
    np.testing.assert_array_equal(message["torque"], torque)


@settings(deadline=None, max_examples=300)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cc", "Cf", "Cs", "Co", "Zl", "Zp", "Zs")),
               min_size=1, max_size=8))
def test_printable_names_round_trip(name):
    _, hello = GOLDEN_FIELDS["hello_player"]
    assert decode(encode(Kind.HELLO, **{**hello, "name": name}))["name"] == name


# --- helpers for the gateway -------------------------------------------------------------------------------
def test_drop_counter_counts_by_reason():
    drops = DropCounter()
    assert drops.decode(GOLDEN["heartbeat"]).kind is Kind.HEARTBEAT
    for case in ("empty", "body_cut_by_one", "one_byte_extra", "version_1", "type_10", "nan_force", "force_501_N",
                 "torque_51_N_m"):
        assert drops.decode(BAD[case][0]) is None
    assert drops.by_reason == {"too_short": 2, "too_long": 1, "bad_version": 1, "unknown_type": 1,
                               "non_finite": 1, "out_of_range": 2}
    assert drops.total == 8


def test_snapshots_of_a_real_match_pass_the_decoder():
    """The ranges leave room for real play: 3 s of an AI match (the serve, strikes, bounces),
    every 10th tick, encodes and decodes to the engine's exact numbers."""
    from engine.dtypes import physics_snapshot_dtype
    from engine.match import Match
    from engine.scene import load_scene

    match = Match(load_scene("match_rigid"), seed=3)
    record = np.zeros(1, physics_snapshot_dtype(2))
    checked = []

    def on_tick(m, tick):
        if tick % 10:
            return
        m.save(record)
        message = decode(wire.snapshot_from_physics(record[0], seq=tick + 1, input_seq=(tick, 0)))
        assert message.tick == int(record[0]["world"]["tick"])
        np.testing.assert_array_equal(message["ball_pos"], record[0]["ball"]["pos"])
        np.testing.assert_array_equal(message["bat_quat"], record[0]["bats"]["quat"])
        assert tuple(message["score"]) == tuple(record[0]["rally"]["score"])
        checked.append(tick)

    match.play(max_ticks=3000, on_tick=on_tick)
    assert len(checked) >= 290


# --- pingpong decode ---------------------------------------------------------------------------------------
def _pingpong(*args):
    return subprocess.run([sys.executable, "-m", "processes", *args], capture_output=True, text=True,
                          timeout=DEADLINE_S, stdin=subprocess.DEVNULL)


def test_decode_command_hex_json():
    done = _pingpong("decode", GOLDEN_HEX["input_force"], "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["ok"] and out["kind"] == "input" and out["seq"] == 42 and out["slot"] == "a"
    assert out["force"] == [12.5, -3.0, 9.81]


def test_decode_command_file_human(tmp_path):
    path = tmp_path / "capture.bin"
    path.write_bytes(GOLDEN["snapshot"])
    done = _pingpong("decode", str(path))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("snapshot  seq 1000  tick 16667") and "phase        struck" in done.stdout


def test_decode_command_bad_message_exits_2_with_the_reason():
    done = _pingpong("decode", BAD["nan_force"][0].hex(), "--json")
    assert done.returncode == 2
    assert json.loads(done.stdout)["reason"] == "non_finite" and "non_finite" in done.stderr
    done = _pingpong("decode", GOLDEN_HEX["heartbeat"][:-2])
    assert done.returncode == 2 and "bad message: too_short" in done.stderr


def test_decode_command_neither_file_nor_hex_exits_2():
    done = _pingpong("decode", "no-such-capture.bin")
    assert done.returncode == 2 and "neither a file nor a hex string" in done.stderr


# --- the cloth net's knots -----------------------------------------------------------------------------------
def test_a_nets_knots_round_trip_within_half_a_step():
    """Knots 85 x 8 (scenes/match.toml's grid) moved up to 5 cm: two messages, and every
    coordinate back within NET_STEP_M / 2 (round to nearest) of what was sent."""
    cols, rows, width, height = 85, 8, 1.83, 0.1525
    rest = wire.net_rest(cols, rows, width, height)
    knots = rest + np.random.default_rng(3).uniform(-0.05, 0.05, rest.shape)
    messages, clamped = wire.net_messages(knots, cols=cols, rows=rows, width=width, height=height, asleep=True,
                                          tick=77)
    assert clamped == 0 and len(messages) == 2 and {len(m) for m in messages} == {wire.SIZES[Kind.NET]}
    back = np.full_like(knots, np.nan)
    for data in messages:
        message = decode(data)
        assert message.tick == 77 and message["asleep"] == 1
        wire.net_knots(message, back)
    np.testing.assert_allclose(back, knots, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # rounding, + float error


def test_a_knot_beyond_the_wires_range_is_clamped_and_counted():
    rest = wire.net_rest(4, 2, 1.0, 0.2)
    knots = rest.copy()
    knots[5, 0] = 0.5  # 50,000 steps: beyond +-32767
    (data,), clamped = wire.net_messages(knots, cols=4, rows=2, width=1.0, height=0.2, asleep=False, tick=1)
    assert clamped == 1
    back = np.zeros_like(knots)
    wire.net_knots(decode(data), back)
    assert back[5, 0] == pytest.approx(wire.NET_MAX_OFFSET * wire.NET_STEP_M, abs=1e-12)  # the range's edge


def test_the_wires_rest_grid_carries_the_nets_built_and_hanging_shapes():
    from net_kernel import build_topology
    from net_kernel.topology import NetSpec

    spec = NetSpec(cols=85, rows=8)
    rest = wire.net_rest(spec.cols, spec.rows, spec.width, spec.height)
    topo = build_topology(spec)
    # the same knot order and columns, bit for bit; the built net's rows start at its hem gap and
    # it rests in its hanging shape, which the offsets carry
    np.testing.assert_array_equal(rest[:, :2], topo.knot_pos[:, :2])
    for shape in (topo.knot_pos, topo.rest_pos):
        messages, clamped = wire.net_messages(shape, cols=spec.cols, rows=spec.rows, width=spec.width,
                                              height=spec.height, asleep=True, tick=0)
        back = np.zeros_like(shape)
        for data in messages:
            wire.net_knots(decode(data), back)
        assert clamped == 0
        np.testing.assert_allclose(back, shape, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # half a 0.01 mm step
