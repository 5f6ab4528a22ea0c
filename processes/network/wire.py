"""The wire protocol: every network message's byte layout, its encoder and its validating decoder.

Each message is one ZeroMQ frame holding one record of a numpy structured dtype: explicit
little-endian fields, packed (no padding; `itemsize` is the sum of the fields), fixed size per
message type. Every message starts with the same 24-byte header:

    off  size  field    type  unit / meaning
      0     4  magic    S4    b"PPNG", the same in every version
      4     2  version  <u2   PROTOCOL_VERSION (2); with magic, frozen for all versions
      6     1  kind     u1    Kind: 1 hello ... 8 goodbye
      7     1  flags    u1    no bits defined in version 2: a set bit is refused (bad_flags)
      8     8  seq      <u8   sender's sequence number, +1 per message it sends on that stream
                              (a session; the gateway's spectator feed numbers its own stream)
     16     8  tick     <i8   physics tick the message refers to, >= 0 (see each message)

Text fields (names, scene, detail) are UTF-8, NUL-padded to their fixed size: the text ends at
the first NUL and every byte after it is NUL; no control or format characters (Unicode Cc, Cf,
Cs, Co, Zl, Zp: no terminal escapes, no bidi overrides), no leading or trailing white space.
Tokens are raw bytes. Enums are one byte each; a value that names no member is refused.

The first 6 bytes (magic, version) never change, so a peer of another version is recognised as
such (BadVersion carries the version it saw) instead of being misread.

Versions: 1, the first, sent every message on the session. 2 adds welcome.feed_port (the welcome
grows from 156 to 158 bytes): a spectator takes snapshots and events from the gateway's PUB
socket (the feed) instead of its session, so the gateway encodes and sends each one once
whatever the number of spectators. The layout changed, so the version did: a version-1 client
is told "version" by the gateway instead of failing on a welcome of a size it does not know.

`decode(buf)` validates everything before any field is used (size exactly right for the type,
magic, version, type, flags, finite numbers, ranges, unit quaternions, enums, text) and returns
a `Message`; a bad buffer raises a `WireError` subclass whose `reason` a gateway counts
(`DropCounter`), and no other exception, whatever the bytes. `encode(kind, ...)` runs the same
validation on what it built, so a peer never sends what the other side would drop.

Floats go on the wire as float64, the engine's own bits: a client rewinds its prediction to the
snapshot's exact state, and a 334-byte snapshot at 60 Hz is 20 kB/s per spectator, so
quantisation would buy little and cost a documented error in every reconciliation.
"""
from __future__ import annotations

import argparse
import enum
import json
import sys
import unicodedata
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.rules import REASONS, Phase, Reason

MAGIC = b"PPNG"
PROTOCOL_VERSION = 2  # 2: welcome.feed_port (the spectator feed); see the module docstring

# Ranges: generous for real play, tight enough that a corrupted or hostile value is refused.
MAX_FORCE_N = 500.0  # |force| of an input; the AI arm's own limit is 50..120 N (engine/ai.py SKILLS)
MAX_TORQUE_NM = 50.0  # |torque| of an input; the AI's limit is 2..4 N m
MAX_POS_M = 8.0  # every position component: twice the distance at which the ball is out of play (4 m)
MAX_SPEED_MS = 100.0  # |velocity| of ball or bat; the fastest recorded smash is ~31 m/s
MAX_SPIN_RADS = 2000.0  # |spin| of the ball; top players reach ~150 rev/s = 940 rad/s
MAX_BAT_ANG_VEL_RADS = 1000.0  # |angular velocity| of a bat
QUAT_TOL = 1e-6  # a quaternion's norm must be within this of 1
MAX_GAMES_WON = 5  # best of 9 is the longest match a scene allows (engine/scene.py)
MAX_BEST_OF = 9
MAX_DT_S = 0.05  # the scene's own bound on a tick's length
TOKEN_SIZE = 16  # bytes of a rejoin token; all zero = none
NAME_SIZE = 32  # bytes of a UTF-8 name, NUL-padded
DETAIL_SIZE = 64  # bytes of a UTF-8 human-readable detail, NUL-padded


class Kind(enum.IntEnum):
    HELLO = 1
    WELCOME = 2
    REJECT = 3
    INPUT = 4
    SNAPSHOT = 5
    EVENT = 6
    HEARTBEAT = 7
    GOODBYE = 8


class Role(enum.IntEnum):
    PLAYER = 1
    SPECTATOR = 2


class Slot(enum.IntEnum):
    """A seat at the table; 0 = none (a spectator, or no preference in a hello)."""

    NONE = 0
    A = 1  # engine player 0, x < 0
    B = 2  # engine player 1, x > 0


class InputMode(enum.IntEnum):
    FORCE = 1  # force and torque held over the ticks until the next input
    TARGET = 2  # a pose for the server's arm controller to reach (within the arm's limits)


class RejectReason(enum.IntEnum):
    FULL = 1  # both player slots taken
    VERSION = 2  # the client speaks another protocol version
    BAD_REQUEST = 3  # the hello was malformed or asked for something impossible
    BAD_TOKEN = 4  # unknown or expired rejoin token
    SHUTTING_DOWN = 5


class EventKind(enum.IntEnum):
    POINT = 1
    GAME = 2
    MATCH = 3  # the match is over


class GoodbyeReason(enum.IntEnum):
    QUIT = 1  # the client leaves
    SHUTDOWN = 2  # the server stops
    TIMEOUT = 3  # no heartbeat from the peer in time
    MATCH_OVER = 4
    KICKED = 5  # too many bad messages


# --- errors ---------------------------------------------------------------------------------------
class WireError(ValueError):
    """A message refused by the decoder (or the encoder); `reason` is a stable code to count."""

    reason = "bad_message"


class TooShort(WireError):
    reason = "too_short"


class TooLong(WireError):
    reason = "too_long"


class BadMagic(WireError):
    reason = "bad_magic"


class BadVersion(WireError):
    reason = "bad_version"

    def __init__(self, message: str, version: int):
        super().__init__(message)
        self.version = version  # the version the peer speaks: a client can tell the user


class UnknownType(WireError):
    reason = "unknown_type"


class BadFlags(WireError):
    reason = "bad_flags"


class NonFinite(WireError):
    reason = "non_finite"


class OutOfRange(WireError):
    reason = "out_of_range"


class BadEnum(WireError):
    reason = "bad_enum"


class BadText(WireError):
    reason = "bad_text"


WIRE_ERRORS = (TooShort, TooLong, BadMagic, BadVersion, UnknownType, BadFlags, NonFinite, OutOfRange,
               BadEnum, BadText)
REASON_CODES = tuple(error.reason for error in WIRE_ERRORS)


# --- layouts --------------------------------------------------------------------------------------
HEADER_FIELDS = [
    ("magic", "S4"),
    ("version", "<u2"),
    ("kind", "u1"),
    ("flags", "u1"),
    ("seq", "<u8"),
    ("tick", "<i8"),
]
HEADER_DTYPE = np.dtype(HEADER_FIELDS)
HEADER_SIZE = HEADER_DTYPE.itemsize  # 24


class _Spec:
    """One message type: its kind, dtype and the meaning of its fields beyond numbers."""

    kind: Kind
    body: list  # numpy field list after the header
    text: dict[str, bool] = {}  # text field -> may be empty
    tokens: tuple[str, ...] = ()  # raw byte fields
    enums: dict[str, type[enum.IntEnum]] = {}
    dtype: np.dtype
    names: tuple[str, ...]

    def __init_subclass__(cls):
        cls.dtype = np.dtype(HEADER_FIELDS + cls.body)
        cls.names = tuple(name for name, *_ in cls.body)

    @staticmethod
    def check(rec) -> None:
        """Ranges and cross-field rules beyond the generic checks (finite, enums, text)."""


class Hello(_Spec):
    """hello, client -> server: asks for a seat or to watch. Header tick: 0.

    Layout, 74 bytes:
        off  size  field  type      unit / meaning
          0    24  header           HEADER_DTYPE
         24     1  role   u1        Role: 1 player, 2 spectator
         25     1  slot   u1        Slot wanted: 0 any free, 1 A, 2 B; 0 for a spectator
         26    32  name   u1[32]    UTF-8, NUL-padded, 1..32 bytes, see text rules
         58    16  token  u1[16]    rejoin token from an earlier welcome; all zero = a new session
                                    (always, for a spectator)
    """

    kind = Kind.HELLO
    body = [("role", "u1"), ("slot", "u1"), ("name", "u1", (NAME_SIZE,)), ("token", "u1", (TOKEN_SIZE,))]
    text = {"name": False}
    tokens = ("token",)
    enums = {"role": Role, "slot": Slot}

    @staticmethod
    def check(rec):
        if rec["role"] == Role.SPECTATOR and rec["slot"] != Slot.NONE:
            raise OutOfRange(f"hello.slot: a spectator asks for no slot, got {int(rec['slot'])}")
        if rec["role"] == Role.SPECTATOR and rec["token"].any():
            raise OutOfRange("hello.token: a spectator has no rejoin token")


class Welcome(_Spec):
    """welcome, server -> client: the seat given and what the client needs to know of the scene.

    Header tick: the server's current tick.

    Layout, 158 bytes:
        off  size  field         type    unit / meaning
          0    24  header                HEADER_DTYPE
         24     1  slot          u1      Slot given: 0 spectator, 1 A, 2 B
         25     1  best_of       u1      games in the match, odd, 1..9
         26     2  snapshot_hz   <u2     snapshots per second the server sends, 1..1000
         28     4  heartbeat_ms  <u4     send a heartbeat at least this often, 1..60000 ms
         32     4  timeout_ms    <u4     a peer silent this long is dropped, heartbeat_ms..600000 ms
         36     8  dt            <f8     s, the physics tick, (0, 0.05]
         44    16  token         u1[16]  rejoin token for this slot; all zero for a spectator only
         60    32  scene         u1[32]  scene name, UTF-8, NUL-padded, non-empty
         92    32  name_a        u1[32]  player A's name, UTF-8, empty while the seat is free
        124    32  name_b        u1[32]  player B's name, UTF-8, empty while the seat is free
        156     2  feed_port     <u2     a spectator's feed: the TCP port, on the host of the session's
                                         endpoint, of the gateway's PUB socket that carries every
                                         snapshot and event (subscribe to all; its own seq stream,
                                         so a gap is a message dropped at the high-water mark), and
                                         none come on the session; 0: none, they come on the
                                         session (always for a player)
    """

    kind = Kind.WELCOME
    body = [("slot", "u1"), ("best_of", "u1"), ("snapshot_hz", "<u2"), ("heartbeat_ms", "<u4"),
            ("timeout_ms", "<u4"), ("dt", "<f8"), ("token", "u1", (TOKEN_SIZE,)), ("scene", "u1", (NAME_SIZE,)),
            ("name_a", "u1", (NAME_SIZE,)), ("name_b", "u1", (NAME_SIZE,)), ("feed_port", "<u2")]
    text = {"scene": False, "name_a": True, "name_b": True}
    tokens = ("token",)
    enums = {"slot": Slot}

    @staticmethod
    def check(rec):
        best_of = int(rec["best_of"])
        if not (1 <= best_of <= MAX_BEST_OF and best_of % 2 == 1):
            raise OutOfRange(f"welcome.best_of: must be odd in 1..{MAX_BEST_OF}, got {best_of}")
        _within("welcome.snapshot_hz", int(rec["snapshot_hz"]), 1, 1000)
        _within("welcome.heartbeat_ms", int(rec["heartbeat_ms"]), 1, 60_000)
        _within("welcome.timeout_ms", int(rec["timeout_ms"]), int(rec["heartbeat_ms"]), 600_000)
        dt = float(rec["dt"])
        if not 0.0 < dt <= MAX_DT_S:
            raise OutOfRange(f"welcome.dt: must be in (0, {MAX_DT_S}] s, got {dt!r}")
        if bool(rec["token"].any()) != (rec["slot"] != Slot.NONE):
            raise OutOfRange("welcome.token: a player gets a non-zero token, a spectator none")
        if rec["feed_port"] and rec["slot"] != Slot.NONE:
            raise OutOfRange("welcome.feed_port: a player's snapshots come on its session, its feed_port is 0")


class Reject(_Spec):
    """reject, server -> client: the hello is turned away; the server closes the session.

    Header tick: the server's current tick.

    Layout, 89 bytes:
        off  size  field   type    unit / meaning
          0    24  header          HEADER_DTYPE
         24     1  reason  u1      RejectReason: 1 full, 2 version, 3 bad_request, 4 bad_token,
                                   5 shutting_down
         25    64  detail  u1[64]  human-readable UTF-8, NUL-padded, may be empty
    """

    kind = Kind.REJECT
    body = [("reason", "u1"), ("detail", "u1", (DETAIL_SIZE,))]
    text = {"detail": True}
    enums = {"reason": RejectReason}


class Input(_Spec):
    """input, player client -> server: what the player's arm does to its own bat.

    Header tick: the tick from which the input holds (the client's predicted tick); header seq
    is echoed back in snapshot.input_seq once the server applied it. The gateway refuses an
    input whose slot is not the session's own, and lets go of it (zero force, same seq) if no
    other input follows within its input_hold_s (0.1 s by default).

    Layout, 130 bytes:
        off  size  field        type      unit / meaning
          0    24  header                 HEADER_DTYPE
         24     1  slot         u1        Slot of the bat, 1 A or 2 B: the sender's own
         25     1  mode         u1        InputMode: 1 force, 2 target
         26    24  force        <f8[3]    N, world frame, |force| <= 500; zero in target mode
         50    24  torque       <f8[3]    N m, world frame, |torque| <= 50; zero in target mode
         74    24  target_pos   <f8[3]    m, world frame, |each| <= 8; zero in force mode
         98    32  target_quat  <f8[4]    (w, x, y, z) unit within 1e-6; zero in force mode
    """

    kind = Kind.INPUT
    body = [("slot", "u1"), ("mode", "u1"), ("force", "<f8", (3,)), ("torque", "<f8", (3,)),
            ("target_pos", "<f8", (3,)), ("target_quat", "<f8", (4,))]
    enums = {"slot": Slot, "mode": InputMode}

    @staticmethod
    def check(rec):
        if rec["slot"] == Slot.NONE:
            raise OutOfRange("input.slot: must be A or B, got 0 (none)")
        if rec["mode"] == InputMode.FORCE:
            _norm_at_most("input.force", rec["force"], MAX_FORCE_N, "N")
            _norm_at_most("input.torque", rec["torque"], MAX_TORQUE_NM, "N m")
            _zero("input.target_pos", rec["target_pos"], "force mode")
            _zero("input.target_quat", rec["target_quat"], "force mode")
        else:
            _zero("input.force", rec["force"], "target mode")
            _zero("input.torque", rec["torque"], "target mode")
            _box("input.target_pos", rec["target_pos"], MAX_POS_M)
            _unit("input.target_quat", rec["target_quat"])


class Snapshot(_Spec):
    """snapshot, server -> every client: the authoritative state at one tick (header tick).

    A player gets it on its session; a spectator on the feed (welcome.feed_port), where header
    seq is the feed's own: the same bytes go to every spectator.

    Ball and bats as the physics worker has them (float64, lossless), the referee's score.

    Layout, 334 bytes:
        off  size  field        type       unit / meaning
          0    24  header                  HEADER_DTYPE
         24    24  ball_pos     <f8[3]     m, world frame, |each| <= 8
         48    24  ball_vel     <f8[3]     m/s, |ball_vel| <= 100
         72    24  ball_spin    <f8[3]     rad/s, angular velocity, |ball_spin| <= 2000
         96    48  bat_pos      <f8[2,3]   m, bats A and B, |each| <= 8
        144    64  bat_quat     <f8[2,4]   (w, x, y, z) bat -> world, unit within 1e-6
        208    48  bat_vel      <f8[2,3]   m/s, |bat_vel[i]| <= 100
        256    48  bat_ang_vel  <f8[2,3]   rad/s, world frame, |bat_ang_vel[i]| <= 1000
        304    16  input_seq    <u8[2]     seq of the last input applied to bat A, B before the step
                                           into this tick (0: none): the snapshot shows the effect
                                           of exactly the inputs up to it (client reconciliation)
        320     4  rally        <u4        rallies started since the match began
        324     4  score        <u2[2]     points of A, B in the current game
        328     2  games_won    u1[2]      games won by A, B, <= 5
        330     1  phase        u1         engine.rules.Phase, 0..5
        331     1  server       u1         player serving this rally: 0 A, 1 B
        332     1  striker      u1         player who struck last (or must serve): 0 A, 1 B
        333     1  winner       i1         -1 while the match is on, else 0 A or 1 B
    """

    kind = Kind.SNAPSHOT
    body = [("ball_pos", "<f8", (3,)), ("ball_vel", "<f8", (3,)), ("ball_spin", "<f8", (3,)),
            ("bat_pos", "<f8", (2, 3)), ("bat_quat", "<f8", (2, 4)), ("bat_vel", "<f8", (2, 3)),
            ("bat_ang_vel", "<f8", (2, 3)), ("input_seq", "<u8", (2,)), ("rally", "<u4"), ("score", "<u2", (2,)),
            ("games_won", "u1", (2,)), ("phase", "u1"), ("server", "u1"), ("striker", "u1"), ("winner", "i1")]
    enums = {"phase": Phase}

    @staticmethod
    def check(rec):
        _box("snapshot.ball_pos", rec["ball_pos"], MAX_POS_M)
        _norm_at_most("snapshot.ball_vel", rec["ball_vel"], MAX_SPEED_MS, "m/s")
        _norm_at_most("snapshot.ball_spin", rec["ball_spin"], MAX_SPIN_RADS, "rad/s")
        for i, side in enumerate("ab"):
            _box(f"snapshot.bat_pos[{side}]", rec["bat_pos"][i], MAX_POS_M)
            _unit(f"snapshot.bat_quat[{side}]", rec["bat_quat"][i])
            _norm_at_most(f"snapshot.bat_vel[{side}]", rec["bat_vel"][i], MAX_SPEED_MS, "m/s")
            _norm_at_most(f"snapshot.bat_ang_vel[{side}]", rec["bat_ang_vel"][i], MAX_BAT_ANG_VEL_RADS, "rad/s")
        _within("snapshot.games_won", int(rec["games_won"].max()), 0, MAX_GAMES_WON)
        _within("snapshot.server", int(rec["server"]), 0, 1)
        _within("snapshot.striker", int(rec["striker"]), 0, 1)
        _within("snapshot.winner", int(rec["winner"]), -1, 1)


class Event(_Spec):
    """event, server -> every client: a rally, a game or the match was decided at header tick.

    On a player's session; on the feed for spectators (as snapshots are).

    Layout, 40 bytes:
        off  size  field      type    unit / meaning
          0    24  header             HEADER_DTYPE
         24     1  event      u1      EventKind: 1 point, 2 game, 3 match
         25     1  winner     i1      0 A, 1 B; -1 only for a let (a point event, reason let)
         26     1  reason     u1      index into engine.rules.REASONS of the deciding rally
         27     1  game       u1      game index, 0-based, < 9
         28     4  score      <u2[2]  points of A, B after the rally (the game's final score)
         32     2  games_won  u1[2]   games won by A, B after the rally, <= 5
         34     2  shots      <u2     strikes in the deciding rally, the service included
         36     4  rally      <u4     rallies started since the match began
    """

    kind = Kind.EVENT
    body = [("event", "u1"), ("winner", "i1"), ("reason", "u1"), ("game", "u1"), ("score", "<u2", (2,)),
            ("games_won", "u1", (2,)), ("shots", "<u2"), ("rally", "<u4")]
    enums = {"event": EventKind}

    @staticmethod
    def check(rec):
        reason = int(rec["reason"])
        if reason >= len(REASONS):
            raise BadEnum(f"event.reason: must index engine.rules.REASONS (0..{len(REASONS) - 1}), got {reason}")
        let = REASONS[reason] is Reason.LET
        winner = int(rec["winner"])
        if let and not (winner == -1 and rec["event"] == EventKind.POINT):
            raise OutOfRange(f"event.winner: a let is a point event without a winner, got winner {winner}")
        if not let:
            _within("event.winner", winner, 0, 1)
        _within("event.game", int(rec["game"]), 0, MAX_BEST_OF - 1)
        _within("event.games_won", int(rec["games_won"].max()), 0, MAX_GAMES_WON)


class Heartbeat(_Spec):
    """heartbeat, both ways: I am alive. Header tick: the sender's latest tick.

    Layout, 32 bytes:
        off  size  field   type  unit / meaning
          0    24  header        HEADER_DTYPE
         24     8  ack     <u8   highest seq received from the peer so far (0: none), for loss counts
    """

    kind = Kind.HEARTBEAT
    body = [("ack", "<u8")]


class Goodbye(_Spec):
    """goodbye, both ways: the session ends. Header tick: the sender's latest tick.

    Layout, 25 bytes:
        off  size  field   type  unit / meaning
          0    24  header        HEADER_DTYPE
         24     1  reason  u1    GoodbyeReason: 1 quit, 2 shutdown, 3 timeout, 4 match_over, 5 kicked
    """

    kind = Kind.GOODBYE
    body = [("reason", "u1")]
    enums = {"reason": GoodbyeReason}


SPECS: dict[Kind, type[_Spec]] = {spec.kind: spec for spec in (Hello, Welcome, Reject, Input, Snapshot, Event,
                                                                 Heartbeat, Goodbye)}
SIZES = {kind: spec.dtype.itemsize for kind, spec in SPECS.items()}


# --- checks ---------------------------------------------------------------------------------------
def _within(name: str, value: int, low: int, high: int) -> None:
    if not low <= value <= high:
        raise OutOfRange(f"{name}: must be in {low}..{high}, got {value}")


def _norm_at_most(name: str, vec, limit: float, unit: str) -> None:
    worst = float(np.abs(vec).max())
    if worst > limit:  # first, so the squares below cannot overflow (1e300 ** 2)
        raise OutOfRange(f"{name}: a component is {worst:.6g} {unit}, |{name.split('.')[-1]}| exceeds {limit:g} {unit}")
    norm = float(np.sqrt(np.dot(vec, vec)))
    if norm > limit:
        raise OutOfRange(f"{name}: |{name.split('.')[-1]}| = {norm:.6g} {unit} exceeds {limit:g} {unit}")


def _box(name: str, vec, limit: float) -> None:
    worst = float(np.abs(vec).max())
    if worst > limit:
        raise OutOfRange(f"{name}: a component is {worst:.6g} m, beyond +-{limit:g} m")


def _unit(name: str, quat) -> None:
    if float(np.abs(quat).max()) > 1.0 + QUAT_TOL:  # first, so the squares below cannot overflow
        raise OutOfRange(f"{name}: a component beyond 1, not a unit quaternion")
    norm = float(np.sqrt(np.dot(quat, quat)))
    if abs(norm - 1.0) > QUAT_TOL:
        raise OutOfRange(f"{name}: norm {norm!r} is not 1 within {QUAT_TOL:g}")


def _zero(name: str, vec, why: str) -> None:
    if np.any(vec != 0.0):
        raise OutOfRange(f"{name}: must be zero in {why}")


_REFUSED_CATEGORIES = {"Cc", "Cf", "Cs", "Co", "Zl", "Zp"}  # controls, format, line/paragraph separators


def _text(name: str, raw: bytes, allow_empty: bool) -> str:
    """A NUL-padded UTF-8 field: the text ends at the first NUL, every byte after is NUL (so
    every accepted message has one encoding), valid UTF-8, no control or format characters (no
    terminal escapes or bidi overrides in a name), no leading or trailing white space."""
    end = raw.find(b"\0")
    if end < 0:
        end = len(raw)
    elif raw[end:].strip(b"\0"):
        raise BadText(f"{name}: bytes after the terminating NUL")
    try:
        text = raw[:end].decode("utf-8")
    except UnicodeDecodeError as err:
        raise BadText(f"{name}: not UTF-8 ({err.reason} at byte {err.start})") from None
    if not text and not allow_empty:
        raise BadText(f"{name}: must not be empty")
    for ch in text:
        if unicodedata.category(ch) in _REFUSED_CATEGORIES:
            raise BadText(f"{name}: control or format character U+{ord(ch):04X}")
    if text != text.strip():
        raise BadText(f"{name}: leading or trailing white space")
    return text


# --- messages -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Message:
    """A validated message: header values and its body fields.

    fields: text as str, tokens as bytes, enums as their IntEnum, float and int arrays as
    read-only numpy arrays, scalars as int or float. `encode(m.kind, seq=m.seq, tick=m.tick,
    flags=m.flags, **m.fields)` gives back the exact bytes.
    """

    kind: Kind
    seq: int
    tick: int
    flags: int
    fields: dict[str, Any]

    def __getitem__(self, name: str):
        return self.fields[name]

    def to_dict(self) -> dict:
        """Plain JSON-able values: enums by name, tokens in hex, arrays as lists."""
        out: dict[str, Any] = {"kind": self.kind.name.lower(), "seq": self.seq, "tick": self.tick, "flags": self.flags}
        for name, value in self.fields.items():
            if isinstance(value, enum.IntEnum):
                value = value.name.lower()
            elif isinstance(value, bytes):
                value = value.hex()
            elif isinstance(value, np.ndarray):
                value = value.tolist()
            out[name] = value
        return out


def decode(buf) -> Message:
    """Validate one message and return it; any bytes-like buffer.

    Raises:
        WireError: a subclass naming the first thing wrong (`reason` is its stable code). No
        other exception for any bytes-like input.
    """
    data = memoryview(buf).tobytes()  # a private copy: the caller may reuse its buffer (recv_into)
    if len(data) < HEADER_SIZE:
        raise TooShort(f"{len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    header = np.frombuffer(data, HEADER_DTYPE, count=1)[0]
    if data[:4] != MAGIC:
        raise BadMagic(f"magic {data[:4]!r}, expected {MAGIC!r}")
    version = int(header["version"])
    if version != PROTOCOL_VERSION:
        raise BadVersion(f"protocol version {version}, this side speaks {PROTOCOL_VERSION}", version)
    try:
        kind = Kind(int(header["kind"]))
    except ValueError:
        raise UnknownType(f"message type {int(header['kind'])} is none of {[int(k) for k in Kind]}") from None
    spec = SPECS[kind]
    size = spec.dtype.itemsize
    if len(data) < size:
        raise TooShort(f"{kind.name.lower()}: {len(data)} bytes, expected {size}")
    if len(data) > size:
        raise TooLong(f"{kind.name.lower()}: {len(data)} bytes, expected {size}")
    if header["flags"]:
        raise BadFlags(f"flags 0x{int(header['flags']):02x}: no flag is defined in version {PROTOCOL_VERSION}")
    tick = int(header["tick"])
    if tick < 0:
        raise OutOfRange(f"tick {tick} is negative")
    rec = np.frombuffer(data, spec.dtype, count=1)[0]
    with np.errstate(all="ignore"):  # subnormals underflow harmlessly, whatever the caller's np.seterr
        return _body(kind, spec, header, rec)


def _body(kind: Kind, spec: type[_Spec], header, rec) -> Message:
    """The body checks of decode, on a header already validated."""
    label = kind.name.lower()
    for name in spec.names:
        value = rec[name]
        if spec.dtype.fields[name][0].base.kind == "f" and not np.isfinite(value).all():
            raise NonFinite(f"{label}.{name}: {np.asarray(value).tolist()} is not finite")
    fields: dict[str, Any] = {}
    for name, enum_type in spec.enums.items():
        try:
            fields[name] = enum_type(int(rec[name]))
        except ValueError:
            raise BadEnum(f"{label}.{name}: {int(rec[name])} is none of "
                          f"{', '.join(f'{int(e)} {e.name.lower()}' for e in enum_type)}") from None
    for name, allow_empty in spec.text.items():
        fields[name] = _text(f"{label}.{name}", rec[name].tobytes(), allow_empty)
    spec.check(rec)
    for name in spec.names:
        if name in fields:
            continue
        value = rec[name]
        if name in spec.tokens:
            fields[name] = value.tobytes()
        elif isinstance(value, np.ndarray):
            fields[name] = value  # a read-only view of the private copy
        elif spec.dtype.fields[name][0].kind == "f":
            fields[name] = float(value)
        else:
            fields[name] = int(value)
    ordered = {name: fields[name] for name in spec.names}
    return Message(kind, int(header["seq"]), int(header["tick"]), int(header["flags"]), ordered)


def _kind_of(kind) -> Kind:
    if isinstance(kind, str):
        try:
            return Kind[kind.upper()]
        except KeyError:
            raise UnknownType(f"no message type {kind!r}; one of {[k.name.lower() for k in Kind]}") from None
    try:
        return Kind(int(kind))
    except ValueError:
        raise UnknownType(f"no message type {kind!r}") from None


def _put_int(rec, name: str, label: str, value) -> None:
    field = rec.dtype.fields[name][0]
    info = np.iinfo(field.base)
    array = np.asarray(value)  # Python ints beyond 64 bits come out as an object array
    whole = array.dtype.kind in "iub" or (array.dtype.kind == "O" and all(isinstance(v, int) for v in array.flat))
    if array.shape != field.shape or not whole:
        raise TypeError(f"{label}: expected integers of shape {field.shape}, got {value!r}")
    if any(not info.min <= int(v) <= info.max for v in array.flat):
        raise OutOfRange(f"{label}: {array.tolist()} does not fit {field.base}")
    rec[name] = array.astype(field.base)


def encode(kind, *, seq: int = 0, tick: int = 0, flags: int = 0, **fields) -> bytes:
    """Build one message of `kind` (a Kind, its number or its name) and validate it.

    fields: every body field of the type, by name (see the type's docstring); text as str,
    tokens as bytes, enums as IntEnum or int, arrays as anything numpy takes.

    Raises:
        TypeError: missing, unknown or wrongly shaped fields (a programming error).
        WireError: a value the peer would refuse (out of range, not finite, bad text ...).
    """
    kind = _kind_of(kind)
    spec = SPECS[kind]
    label = kind.name.lower()
    missing = [name for name in spec.names if name not in fields]
    unknown = [name for name in fields if name not in spec.names]
    if missing or unknown:
        raise TypeError(f"{label}: missing fields {missing}, unknown fields {unknown}")
    rec = np.zeros((), spec.dtype)
    rec["magic"] = MAGIC
    rec["version"] = PROTOCOL_VERSION
    rec["kind"] = kind
    _put_int(rec, "flags", "flags", flags)
    _put_int(rec, "seq", "seq", seq)
    _put_int(rec, "tick", "tick", tick)
    for name in spec.names:
        value = fields[name]
        field = spec.dtype.fields[name][0]
        where = f"{label}.{name}"
        if name in spec.text:
            raw = value.encode("utf-8") if isinstance(value, str) else None
            if raw is None:
                raise TypeError(f"{where}: expected str, got {type(value).__name__}")
            if len(raw) > field.itemsize:
                raise BadText(f"{where}: {len(raw)} UTF-8 bytes, at most {field.itemsize}")
            rec[name] = np.frombuffer(raw.ljust(field.itemsize, b"\0"), np.uint8)
        elif name in spec.tokens:
            if not isinstance(value, (bytes, bytearray)) or len(value) != field.itemsize:
                raise TypeError(f"{where}: expected {field.itemsize} bytes, got {value!r}")
            rec[name] = np.frombuffer(bytes(value), np.uint8)
        elif field.base.kind == "f":
            array = np.asarray(value, dtype=np.float64)
            if array.shape != field.shape:
                raise TypeError(f"{where}: expected shape {field.shape}, got {array.shape}")
            rec[name] = array
        else:
            _put_int(rec, name, where, value)
    data = rec.tobytes()
    decode(data)  # the same validation the peer will run: never send what it would drop
    return data


# --- helpers for the gateway ----------------------------------------------------------------------
def snapshot_from_physics(record, *, seq: int, input_seq=(0, 0)) -> bytes:
    """A snapshot message from one engine.dtypes.physics_snapshot_dtype(2) record."""
    ball, bats, world, rally = record["ball"], record["bats"], record["world"], record["rally"]
    return encode(Kind.SNAPSHOT, seq=seq, tick=int(world["tick"]), ball_pos=ball["pos"], ball_vel=ball["vel"],
                  ball_spin=ball["spin"], bat_pos=bats["pos"], bat_quat=bats["quat"], bat_vel=bats["vel"],
                  bat_ang_vel=bats["ang_vel"], input_seq=np.asarray(input_seq, np.uint64),
                  rally=int(rally["rally"]), score=rally["score"], games_won=rally["games_won"],
                  phase=int(rally["phase"]), server=int(rally["server"]), striker=int(rally["striker"]),
                  winner=int(rally["winner"]))


class DropCounter:
    """Messages dropped, counted by WireError reason: what a gateway reports."""

    def __init__(self):
        self.by_reason: Counter[str] = Counter()

    def decode(self, buf) -> Message | None:
        """The message, or None after counting why it was dropped."""
        try:
            return decode(buf)
        except WireError as err:
            self.by_reason[err.reason] += 1
            return None

    @property
    def total(self) -> int:
        return sum(self.by_reason.values())


# --- pingpong decode ------------------------------------------------------------------------------
def _read_capture(source: str) -> bytes:
    try:
        is_file = Path(source).is_file()
    except OSError:  # a long hex string is too long for a file name
        is_file = False
    if is_file:
        return Path(source).read_bytes()
    text = "".join(source.split()).replace(":", "")
    if text[:2].lower() == "0x":
        text = text[2:]
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise ValueError(f"{source!r} is neither a file nor a hex string") from None


def _human(message: Message) -> str:
    lines = [f"{message.kind.name.lower()}  seq {message.seq}  tick {message.tick}  flags 0x{message.flags:02x}  "
             f"({SIZES[message.kind]} bytes, protocol {PROTOCOL_VERSION})"]
    for name, value in message.to_dict().items():
        if name in ("kind", "seq", "tick", "flags"):
            continue
        if isinstance(value, float) or (isinstance(value, list) and value and isinstance(value[0], float)):
            value = json.dumps(value)
        elif isinstance(value, str) and name in SPECS[message.kind].text:
            value = json.dumps(value, ensure_ascii=False)
        lines.append(f"  {name:<12} {value}")
    return "\n".join(lines)


def decode_command(args: argparse.Namespace) -> int:
    """`pingpong decode FILE|HEX`: pretty-print one captured message; exit 2 if it is bad."""
    try:
        data = _read_capture(args.message)
    except (ValueError, OSError) as err:
        print(f"pingpong decode: {err}", file=sys.stderr)
        return 2
    try:
        message = decode(data)
    except WireError as err:
        if args.json:
            print(json.dumps({"ok": False, "reason": err.reason, "detail": str(err), "bytes": len(data)}))
        print(f"pingpong decode: bad message: {err.reason}: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"ok": True, **message.to_dict()}, ensure_ascii=False))
    else:
        print(_human(message))
    return 0


__all__ = ["MAGIC", "PROTOCOL_VERSION", "Kind", "Role", "Slot", "InputMode", "RejectReason", "EventKind",
           "GoodbyeReason", "WireError", "TooShort", "TooLong", "BadMagic", "BadVersion", "UnknownType", "BadFlags",
           "NonFinite", "OutOfRange", "BadEnum", "BadText", "WIRE_ERRORS", "REASON_CODES", "HEADER_DTYPE",
           "HEADER_SIZE", "SPECS", "SIZES", "Message", "decode", "encode", "snapshot_from_physics", "DropCounter",
           "decode_command"]
