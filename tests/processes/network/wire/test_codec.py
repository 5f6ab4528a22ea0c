"""The wire's codec: messages round trip, and the decoder refuses every bad message with a counted
WireError and never anything else (processes.network.wire.codec, .checks)."""
import json
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.play.rules import REASONS, Phase, Reason
from processes.network import wire
from processes.network.wire import (BadEnum, BadFlags, BadMagic, BadText, BadVersion, DropCounter, EventKind,
                                    InputMode, Kind, NonFinite, OutOfRange, Role, Slot, TooLong, TooShort, UnknownType,
                                    WireError, decode, encode)
from tests.helpers.golden import GOLDEN, GOLDEN_FIELDS, NET_OFFSET, R, TOKEN, patched


def _reencode(message):
    return encode(message.kind, seq=message.seq, tick=message.tick, flags=message.flags, **message.fields)


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
    assert json.loads(json.dumps(message.to_dict(), ensure_ascii=False))["kind"] == kind.name.lower()


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
    "version_4": (_with_header("heartbeat", version=4), BadVersion),  # before the served scene
    "version_6": (_with_header("heartbeat", version=6), BadVersion),
    "type_0": (_with_header("heartbeat", kind=0), UnknownType),
    "type_12": (_with_header("heartbeat", kind=12), UnknownType),
    "type_255": (_with_header("heartbeat", kind=255), UnknownType),
    "flags": (_with_header("heartbeat", flags=0x80), BadFlags),
    "negative_tick": (_with_header("heartbeat", tick=-1), OutOfRange),
    "nan_force": (patched("input_force", force=(math.nan, 0, 0)), NonFinite),
    "inf_torque": (patched("input_force", torque=(0, -math.inf, 0)), NonFinite),
    "nan_ball_pos": (patched("snapshot", ball_pos=(0, 0, math.nan)), NonFinite),
    "nan_in_unused_target": (patched("input_force", target_quat=(math.nan, 0, 0, 0)), NonFinite),
    "inf_dt": (patched("welcome_a", dt=math.inf), NonFinite),
    "force_501_N": (patched("input_force", force=(300.0, 400.0, 10.0)), OutOfRange),
    "torque_51_N_m": (patched("input_force", torque=(0.0, 0.0, 51.0)), OutOfRange),
    "target_far_away": (patched("input_target", target_pos=(8.5, 0, 0)), OutOfRange),
    "target_quat_not_unit": (patched("input_target", target_quat=(1.0, 0, 0, 2e-3)), OutOfRange),
    "force_in_target_mode": (patched("input_target", force=(1.0, 0, 0)), OutOfRange),
    "input_for_no_slot": (patched("input_force", slot=0), OutOfRange),
    "target_in_force_mode": (patched("input_force", target_pos=(0.0, 0.1, 0.0)), OutOfRange),
    "hello_tick_not_0": (_with_header("hello_player", tick=7), OutOfRange),
    "ball_far_away": (patched("snapshot", ball_pos=(0, 100.0, 0)), OutOfRange),
    "ball_too_fast": (patched("snapshot", ball_vel=(0, 0, 101.0)), OutOfRange),
    "ball_spin_wild": (patched("snapshot", ball_spin=(2001.0, 0, 0)), OutOfRange),
    "bat_quat_zero": (patched("snapshot", bat_quat=((0, 0, 0, 0), (1, 0, 0, 0))), OutOfRange),
    "games_won_6": (patched("snapshot", games_won=(6, 0)), OutOfRange),
    "server_2": (patched("snapshot", server=2), OutOfRange),
    "winner_minus_2": (patched("snapshot", winner=-2), OutOfRange),
    "best_of_even": (patched("welcome_a", best_of=4), OutOfRange),
    "scene_parts_0": (patched("scene_part", parts=0, part=0), OutOfRange),
    "scene_parts_17": (patched("scene_part", parts=17), OutOfRange),
    "scene_part_past_parts": (patched("scene_part", part=2), OutOfRange),
    "scene_size_0": (patched("scene_part", size=0), OutOfRange),
    "scene_text_past_size": (patched("scene_part", size=24), OutOfRange),
    "dt_zero": (patched("welcome_a", dt=0.0), OutOfRange),
    "timeout_below_heartbeat": (patched("welcome_a", timeout_ms=100), OutOfRange),
    "player_without_token": (patched("welcome_a", token=np.zeros(16, np.uint8)), OutOfRange),
    "spectator_asks_a_slot": (patched("hello_player", role=Role.SPECTATOR, slot=Slot.A), OutOfRange),
    "let_with_winner": (patched("event_point", reason=REASONS.index(Reason.LET)), OutOfRange),
    "role_0": (patched("hello_player", role=0), BadEnum),
    "role_3": (patched("hello_player", role=3), BadEnum),
    "slot_3": (patched("welcome_a", slot=3), BadEnum),
    "input_mode_0": (patched("input_force", mode=0), BadEnum),
    "phase_6": (patched("snapshot", phase=6), BadEnum),
    "reject_reason_0": (patched("reject_full", reason=0), BadEnum),
    "event_kind_4": (patched("event_point", event=4), BadEnum),
    "rules_reason_past_the_end": (patched("event_point", reason=len(REASONS)), BadEnum),
    "goodbye_reason_99": (patched("goodbye_shutdown", reason=99), BadEnum),
    "net_cut_by_one": (GOLDEN["net"][:-1], TooShort),
    "net_one_byte_extra": (GOLDEN["net"] + b"\0", TooLong),
    "net_offset_minus_32768": (patched("net", offset=np.where(np.arange(640)[:, None] == 3, -32768, NET_OFFSET)),
                               OutOfRange),
    "net_offset_past_count": (patched("net", offset=np.where(np.arange(640)[:, None] == 40, 1, NET_OFFSET)),
                              OutOfRange),
    "net_count_0": (patched("net", count=0), OutOfRange),
    "net_count_641": (patched("net", count=641), OutOfRange),
    "net_past_the_last_knot": (patched("net", first=641), OutOfRange),
    "net_one_column": (patched("net", cols=1, first=0), OutOfRange),
    "net_asleep_2": (patched("net", asleep=2), OutOfRange),
    "net_width_zero": (patched("net", width=0.0), OutOfRange),
    "net_height_9": (patched("net", height=9.0), OutOfRange),
    "net_nan_width": (patched("net", width=math.nan), NonFinite),
}


def _name_bytes(raw: bytes) -> np.ndarray:
    return np.frombuffer(raw.ljust(wire.NAME_SIZE, b"\0"), np.uint8)


BAD.update({
    "name_empty": (patched("hello_player", name=_name_bytes(b"")), BadText),
    "name_not_utf8": (patched("hello_player", name=_name_bytes(b"Ad\xff")), BadText),
    "name_cut_mid_character": (patched("hello_player", name=_name_bytes("卓".encode()[:2])), BadText),
    "name_escape_sequence": (patched("hello_player", name=_name_bytes(b"\x1b[2JAda")), BadText),
    "name_bidi_override": (patched("hello_player", name=_name_bytes("Ada\u202e".encode())), BadText),
    "name_nul_inside": (patched("hello_player", name=_name_bytes(b"Ad\0a")), BadText),
    "name_trailing_space": (patched("hello_player", name=_name_bytes(b"Ada ")), BadText),
    "name_full_32_bytes_of_newline": (patched("hello_player", name=_name_bytes(b"\n" * 32)), BadText),
    "scene_empty": (patched("welcome_a", scene=_name_bytes(b"")), BadText),
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
    assert decode(patched("input_target", target_quat=q * (1 + 0.9e-6)))  # |q| - 1 = 0.9e-6: accepted
    with pytest.raises(OutOfRange):
        decode(patched("input_target", target_quat=q * (1 + 1.1e-6)))  # 1.1e-6: refused


def test_force_limit_is_on_the_norm_500_N():
    assert decode(patched("input_force", force=(300.0, 400.0, 0.0)))  # |F| = 500 N exactly: accepted
    with pytest.raises(OutOfRange):
        decode(patched("input_force", force=(300.0, 400.0, 1e-3)))  # 500.000001 N


def test_a_let_is_a_point_without_winner():
    let = patched("event_point", reason=REASONS.index(Reason.LET), winner=-1)
    assert decode(let)["winner"] == -1
    with pytest.raises(OutOfRange):
        decode(patched("event_point", winner=-1))  # out_long needs a winner


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


def _own_force_input(data: bytes, slot: Slot) -> bool:
    try:
        message = decode(data)
    except WireError:
        return False
    return message.kind == Kind.INPUT and message["slot"] == slot and message["mode"] == InputMode.FORCE


@st.composite
def _mutated_input(draw):
    fields = {"slot": draw(st.sampled_from([Slot.A, Slot.B])), "mode": InputMode.FORCE,
              "force": [draw(_force) for _ in range(3)],
              "torque": [draw(_torque) for _ in range(3)],
              "target_pos": (0, 0, 0), "target_quat": (0, 0, 0, 0)}
    data = bytearray(encode(Kind.INPUT, seq=draw(st.integers(0, 2**64 - 1)), tick=draw(st.integers(0, 2**62)),
                            **fields))
    for _ in range(draw(st.integers(0, 3))):
        if len(data) < wire.SIZES[Kind.INPUT]:  # cut short: decode refuses it whatever follows
            break
        what = draw(st.sampled_from(["set", "flip", "float", "limit", "cut"]))
        if what == "set":
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        elif what == "flip":
            data[draw(st.integers(0, len(data) - 1))] ^= 1 << draw(st.integers(0, 7))
        elif what == "float":  # NaN, inf, huge, tiny, anywhere in the body
            at = draw(st.integers(24, len(data) - 8))
            data[at:at + 8] = np.float64(draw(st.floats(allow_nan=True, allow_infinity=True))).tobytes()
        elif what == "limit":  # a force or torque component on its limit, give or take an ulp
            at = draw(st.sampled_from([26, 34, 42, 50, 58, 66]))
            limit = wire.MAX_FORCE_N if at < 50 else wire.MAX_TORQUE_NM
            value = np.nextafter(limit, draw(st.sampled_from([0.0, np.inf]))) if draw(st.booleans()) else limit
            data[at:at + 8] = np.float64(value * draw(st.sampled_from([1, -1]))).tobytes()
        else:
            del data[draw(st.integers(0, len(data) - 1)):]
    return bytes(data)


@settings(deadline=None, max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_mutated_input(), min_size=1, max_size=12), st.sampled_from([Slot.A, Slot.B]))
def test_the_batch_input_check_passes_only_what_decode_accepts_as_the_bats_force_input(batch, slot):
    # the gateway's coalescing relies on it: a message it passes is counted as a replaced input,
    # never decoded, so it must never pass what decode refuses
    passed = wire.own_force_inputs(batch, slot)
    accepted = [_own_force_input(data, slot) for data in batch]
    assert all(a for p, a in zip(passed, accepted) if p)
    # and it passes every ordinary valid input (only a norm within 1e-9 of its limit is left to decode)
    assert all(p for p, a, data in zip(passed, accepted, batch) if a and not _near_a_limit(data))


def _near_a_limit(data: bytes) -> bool:
    message = decode(data)
    return (abs(np.linalg.norm(message["force"]) - wire.MAX_FORCE_N) < 1e-6
            or abs(np.linalg.norm(message["torque"]) - wire.MAX_TORQUE_NM) < 1e-6)


# --- helpers for the gateway -------------------------------------------------------------------------------
def test_drop_counter_counts_by_reason():
    drops = DropCounter()
    assert drops.decode(GOLDEN["heartbeat"]).kind is Kind.HEARTBEAT
    for case in ("empty", "body_cut_by_one", "one_byte_extra", "version_1", "type_12", "nan_force", "force_501_N",
                 "torque_51_N_m"):
        assert drops.decode(BAD[case][0]) is None
    assert drops.by_reason == {"too_short": 2, "too_long": 1, "bad_version": 1, "unknown_type": 1,
                               "non_finite": 1, "out_of_range": 2}
    assert drops.total == 8


def test_snapshots_of_a_real_match_pass_the_decoder():
    """The ranges leave room for real play: 3 s of an AI match (the serve, strikes, bounces),
    every 10th tick, encodes and decodes to the engine's exact numbers."""
    from engine.physics.dtypes import physics_snapshot_dtype
    from engine.physics.scene import load_scene
    from engine.play.match import Match

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


