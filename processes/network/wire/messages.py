"""Every wire message's byte layout: the header, the enums, the limits and the nine message types."""
from __future__ import annotations

import enum

import numpy as np

from engine.play.rules import REASONS, Phase, Reason
from processes.network.wire.checks import BadEnum, OutOfRange, _box, _norm_at_most, _unit, _within, _zero

MAGIC = b"PPNG"
PROTOCOL_VERSION = 5  # 2: welcome.feed_port (the spectator feed); 3: net (the cloth net's knots);
# 4: snapshot.realtime_factor (how fast the server's match clock runs); 5: welcome.scene_digest,
# scene_request and scene (the served scene travels with the match)

# Ranges: generous for real play, tight enough that a corrupted or hostile value is refused.
MAX_FORCE_N = 500.0  # |force| of an input; the AI arm's own limit is 50..120 N (engine/play/ai/skill.py SKILLS)
MAX_TORQUE_NM = 50.0  # |torque| of an input; the AI's limit is 2..4 N m
MAX_POS_M = 8.0  # every position component: twice the distance at which the ball is out of play (4 m)
MAX_SPEED_MS = 100.0  # |velocity| of ball or bat; the fastest recorded smash is ~31 m/s
MAX_SPIN_RADS = 2000.0  # |spin| of the ball; top players reach ~150 rev/s = 940 rad/s
MAX_BAT_ANG_VEL_RADS = 1000.0  # |angular velocity| of a bat
MAX_GAMES_WON = 5  # best of 9 is the longest match a scene allows (engine/physics/scene.py)
MAX_BEST_OF = 9  # games of the longest match a scene allows
MAX_DT_S = 0.05  # the scene's own bound on a tick's length (engine.physics.scene.MAX_DT)
SERVER_SILENCE_BEATS = 4  # a client takes a server silent for max(timeout_ms, this many heartbeat_ms) as gone
MAX_REALTIME_FACTOR = 1000.0  # snapshot.realtime_factor: a realtime server runs at most about 1
TOKEN_SIZE = 16  # bytes of a rejoin token; all zero = none
NAME_SIZE = 32  # bytes of a UTF-8 name, NUL-padded
DETAIL_SIZE = 64  # bytes of a UTF-8 human-readable detail, NUL-padded
NET_STEP_M = 1e-5  # one unit of a net message's knot offset: 0.01 mm
NET_MAX_OFFSET = 32767  # |offset| in steps: 0.32767 m from the rest grid, twice the net's height
NET_CHUNK_KNOTS = 640  # knots per net message: 3891 bytes, within MAX_FRAME_BYTES like every message
NET_MAX_SIDE = 4000  # knots along a side of the net at most (net_kernel.topology's own bound)
DIGEST_SIZE = 8  # bytes of a scene's digest: engine.physics.scene.scene_digest's 16 hex digits
SCENE_CHUNK = 4000  # bytes of scene text a scene_part carries: 4036 bytes, within MAX_FRAME_BYTES
MAX_SCENE_PARTS = 16  # scene_parts of one scene at most: 64000 bytes of TOML
MAX_SCENE_REQUESTS = 4  # scene requests one session may make; more count as bad messages
NO_TOKEN = bytes(TOKEN_SIZE)  # the token of no seat: a spectator's, or a player's first hello

# What the gateway promises every session, published with the limits above (docs/protocol.md).
MAX_FRAME_BYTES = 4096  # libzmq disconnects a peer sending a bigger frame (MAXMSGSIZE)
MAX_BAD = 64  # bad messages one session may send before it is kicked
NET_HZ = 60  # net messages per second at most, while the net is awake: the page's frame rate
# A remote arm's input holds at most this long: a client that stalls (or whose snapshots stop)
# must not leave its bat pushed by a constant force (120 N on a 0.17 kg bat is 70 m/s in 0.1 s).
# The physics counts it in match time from the tick it applied the input
# (engine.physics.compiled.CompiledScene.ticks: at least that one tick), then brakes the bat; a
# client's prediction lets go of its input as the physics does.
INPUT_HOLD_S = 0.1  # s of match time, an input is let go of this long after the physics applied it


# The gateway's settings that a client sees, at their defaults (server.gateway.GatewayConfig
# takes them from here; docs/protocol.md publishes them).
DEFAULT_SNAPSHOT_HZ = 60  # snapshots per second of match time
DEFAULT_HEARTBEAT_S = 0.5  # s between the gateway's heartbeats to a session
DEFAULT_TIMEOUT_S = 5.0  # s of silence after which a peer is dropped
DEFAULT_GRACE_S = 30.0  # s a dropped player's seat waits for its token
DEFAULT_SNDHWM = 32  # messages queued per peer before its newest are dropped
DEFAULT_MAX_SPECTATORS = 64  # spectator sessions at most


class Kind(enum.IntEnum):
    HELLO = 1  # client asks for a seat or to watch
    WELCOME = 2  # the seat given, the session's parameters
    REJECT = 3  # the hello turned away
    INPUT = 4  # a player's force and torque on its own bat
    SNAPSHOT = 5  # the authoritative state at one tick
    EVENT = 6  # a point, a game or the match decided
    HEARTBEAT = 7  # alive, and the highest seq received
    GOODBYE = 8  # the session ends
    NET = 9  # the cloth net's knots, for display (protocol 3)
    SCENE_REQUEST = 10  # a client asks for the served scene's text (protocol 5)
    SCENE_PART = 11  # one part of the served scene's TOML text (protocol 5)


class Role(enum.IntEnum):
    PLAYER = 1  # plays a bat: inputs in, snapshots and events on its session
    SPECTATOR = 2  # watches: controls nothing, snapshots and events on the feed


class Slot(enum.IntEnum):
    """A seat at the table; 0 = none (a spectator, or no preference in a hello)."""

    NONE = 0  # a spectator, or any free seat in a hello
    A = 1  # engine player 0, x < 0
    B = 2  # engine player 1, x > 0

    @property
    def bat(self) -> int:
        """The engine's index of this seat's bat and player (A: 0, B: 1), the index of every
        per-bat array (scene.bats, the state's bats, snapshot.input_seq). Raises ValueError for
        NONE, which has no bat."""
        if self is Slot.NONE:
            raise ValueError("Slot.NONE (a spectator) has no bat")
        return int(self) - 1

    @classmethod
    def of_bat(cls, bat: int) -> Slot:
        """The seat of the engine's bat `bat` (0: A, 1: B)."""
        return cls(bat + 1)


class InputMode(enum.IntEnum):
    FORCE = 1  # force and torque held over the ticks until the next input
    TARGET = 2  # reserved: a pose for a server-side arm controller; protocol 3 to 5 gateways refuse it


class RejectReason(enum.IntEnum):
    FULL = 1  # both player slots taken
    VERSION = 2  # the client speaks another protocol version
    BAD_REQUEST = 3  # the hello was malformed or asked for something impossible
    BAD_TOKEN = 4  # unknown or expired rejoin token
    SHUTTING_DOWN = 5  # the server is stopping


class EventKind(enum.IntEnum):
    POINT = 1  # a rally is decided (or a let is replayed)
    GAME = 2  # the rally decided a game too (sent after its point)
    MATCH = 3  # the rally decided the match (sent after its point and game)


class GoodbyeReason(enum.IntEnum):
    QUIT = 1  # the client leaves
    SHUTDOWN = 2  # the server stops
    TIMEOUT = 3  # no heartbeat from the peer in time
    MATCH_OVER = 4  # the match is decided or reached its tick limit
    KICKED = 5  # too many bad messages, or the seat's token was used by a new connection
    UNKNOWN_SESSION = 6  # the server has no session for this connection (it restarted): hello again
    SERVER_ERROR = 7  # the server failed (a worker failed past its restart budget): the match is over, unfinished


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
    """hello, client -> server: asks for a seat or to watch. Header tick: 0 (a hello with
    another is rejected bad_request).

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
        if rec["tick"] != 0:
            raise OutOfRange(f"hello: header tick {int(rec['tick'])}, a hello's is 0")
        if rec["role"] == Role.SPECTATOR and rec["slot"] != Slot.NONE:
            raise OutOfRange(f"hello.slot: a spectator asks for no slot, got {int(rec['slot'])}")
        if rec["role"] == Role.SPECTATOR and rec["token"].any():
            raise OutOfRange("hello.token: a spectator has no rejoin token")


class Welcome(_Spec):
    """welcome, server -> client: the seat given and what the client needs to know of the scene.

    Header tick: the server's current tick.

    Layout, 166 bytes:
        off  size  field         type    unit / meaning
          0    24  header                HEADER_DTYPE
         24     1  slot          u1      Slot given: 0 spectator, 1 A, 2 B
         25     1  best_of       u1      games in the match, odd, 1..9
         26     2  snapshot_hz   <u2     snapshots per second of match time, 1..1000
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
                                         none come on the session but the net's state right after
                                         the welcome; 0: none, they come on the session (always
                                         for a player)
        158     8  scene_digest  u1[8]   the served scene's digest (engine.physics.scene.scene_digest: sha256
                                         over what it simulates, its first 8 bytes); a client
                                         without that scene asks for it (scene_request)
    """

    kind = Kind.WELCOME
    body = [("slot", "u1"), ("best_of", "u1"), ("snapshot_hz", "<u2"), ("heartbeat_ms", "<u4"),
            ("timeout_ms", "<u4"), ("dt", "<f8"), ("token", "u1", (TOKEN_SIZE,)), ("scene", "u1", (NAME_SIZE,)),
            ("name_a", "u1", (NAME_SIZE,)), ("name_b", "u1", (NAME_SIZE,)), ("feed_port", "<u2"),
            ("scene_digest", "u1", (DIGEST_SIZE,))]
    text = {"scene": False, "name_a": True, "name_b": True}
    tokens = ("token", "scene_digest")
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

    Header tick: the client's estimate of the server tick at which the input takes effect (its
    predicted present); the server does not schedule by it: an input holds from the first tick
    the physics steps after it arrived, until the next input, and snapshot.input_seq says from
    which tick (header seq is echoed there once the server applied it). The gateway refuses an
    input whose slot is not the session's own; the physics lets go of it if no other input
    follows within input_hold_s (0.1 s of match time by default) and then brakes the bat to
    rest itself, every tick (engine.play.arm.brake_force). Mode 2 (target) is
    reserved: valid on the wire, refused by this gateway like another bat's input. No input is
    answered: one that breaks a field's rule below (a force-mode input whose target fields are
    not all zero, say) is dropped and counted as a bad message, a refused one is counted as
    refused, and snapshot.input_seq keeps naming the input that holds.

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

    Ball and bats as the physics worker has them (float64, lossless), the referee's score, and
    how fast the match's clock runs against the wall clock.

    Layout, 338 bytes:
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
        320     4  rally        <u4        the rally in play: rallies started (tossed) since the match
                                           began, so 1 during the first
        324     4  score        <u2[2]     points of A, B in the current game
        328     2  games_won    u1[2]      games won by A, B, <= 5
        330     1  phase        u1         engine.play.rules.Phase, 0..5
        331     1  server       u1         player serving this rally: 0 A, 1 B
        332     1  striker      u1         player who struck last (or must serve): 0 A, 1 B
        333     1  winner       i1         -1 while the match is on, else 0 A or 1 B
        334     4  realtime_factor <f4     match seconds per wall second over the server's last
                                           second (1: realtime; below 1 the machine cannot keep up
                                           and the match runs slower; 0 while it stands: paused,
                                           not started), 0..MAX_REALTIME_FACTOR
    """

    kind = Kind.SNAPSHOT
    body = [("ball_pos", "<f8", (3,)), ("ball_vel", "<f8", (3,)), ("ball_spin", "<f8", (3,)),
            ("bat_pos", "<f8", (2, 3)), ("bat_quat", "<f8", (2, 4)), ("bat_vel", "<f8", (2, 3)),
            ("bat_ang_vel", "<f8", (2, 3)), ("input_seq", "<u8", (2,)), ("rally", "<u4"), ("score", "<u2", (2,)),
            ("games_won", "u1", (2,)), ("phase", "u1"), ("server", "u1"), ("striker", "u1"), ("winner", "i1"),
            ("realtime_factor", "<f4")]
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
        if not 0.0 <= float(rec["realtime_factor"]) <= MAX_REALTIME_FACTOR:
            raise OutOfRange(f"snapshot.realtime_factor: must be in 0..{MAX_REALTIME_FACTOR:g}, "
                             f"got {float(rec['realtime_factor'])}")


class Event(_Spec):
    """event, server -> every client: a rally, a game or the match was decided at header tick.

    On a player's session; on the feed for spectators (as snapshots are).

    Layout, 40 bytes:
        off  size  field      type    unit / meaning
          0    24  header             HEADER_DTYPE
         24     1  event      u1      EventKind: 1 point, 2 game, 3 match
         25     1  winner     i1      0 A, 1 B; -1 only for a let (a point event, reason let)
         26     1  reason     u1      index into engine.play.rules.REASONS of the deciding rally
         27     1  game       u1      game index, 0-based, < 9
         28     4  score      <u2[2]  points of A, B after the rally (the game's final score)
         32     2  games_won  u1[2]   games won by A, B after the rally, <= 5
         34     2  shots      <u2     strikes in the deciding rally, the service included
         36     4  rally      <u4     the rally it decided: the number its snapshots carried
    """

    kind = Kind.EVENT
    body = [("event", "u1"), ("winner", "i1"), ("reason", "u1"), ("game", "u1"), ("score", "<u2", (2,)),
            ("games_won", "u1", (2,)), ("shots", "<u2"), ("rally", "<u4")]
    enums = {"event": EventKind}

    @staticmethod
    def check(rec):
        reason = int(rec["reason"])
        if reason >= len(REASONS):
            raise BadEnum(f"event.reason: must index engine.play.rules.REASONS (0..{len(REASONS) - 1}), got {reason}")
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
         24     1  reason  u1    GoodbyeReason: 1 quit, 2 shutdown, 3 timeout, 4 match_over, 5 kicked,
                                 6 unknown_session, 7 server_error
    """

    kind = Kind.GOODBYE
    body = [("reason", "u1")]
    enums = {"reason": GoodbyeReason}


class Net(_Spec):
    """net, server -> every client: the cloth net's knots at header tick (the net worker's state).

    Sent only for a scene with a cloth net (a rigid net is a panel: no net message ever comes):
    at most 60 times a second (and never more often than snapshots) while the net is awake,
    once when it falls asleep (asleep 1: it stays in that shape until the next net message),
    and once on each session right after its welcome (a spectator's too), so a client knows the
    net from its first moment. A player gets them on its session, a spectator on the feed. The
    net's knots need more than one message: each carries `count` knots from knot `first`;
    every message of one tick has the same header tick. Write each message's knots into an
    array of cols x rows knots as it comes (a lost one leaves its knots a frame old).

    Each message says its grid: cols x rows knots, numbered row-major from the bottom row
    (knot = row * cols + col), whose rest position is the regular grid in the plane x = 0:
    (0, -width / 2 + col * width / (cols - 1), row * height / (rows - 1)) m, the net as
    net_kernel.topology builds it. A knot is at rest + offset * NET_STEP_M (0.01 mm steps).
    The quantisation error (5 um at most) is far below a pixel of any view of the table and the
    range (+-0.33 m) beyond any bulge a ball makes in a 15 cm net; a knot beyond it is drawn at
    its edge (the gateway clamps and counts). The knots are for display only: the server's
    physics is authoritative and a client's prediction never uses them.

    Layout, 3891 bytes:
        off  size  field     type        unit / meaning
          0    24  header                HEADER_DTYPE
         24     2  cols      <u2         knots along y, 2..4000
         26     2  rows      <u2         knots along z, 2..4000
         28     4  first     <u4         the knot of offset[0]; first + count <= cols * rows
         32     2  count     <u2         knots in this message, 1..640
         34     1  asleep    u1          1: the net fell asleep in this shape, 0: it moves
         35     8  width     <f8         m, the rest grid's extent along y, (0, 16]
         43     8  height    <f8         m, the rest grid's extent along z, (0, 8]
         51  3840  offset    <i2[640,3]  knots first .. first + count - 1: position - rest, in
                                         NET_STEP_M (1e-5 m), each in -32767..32767; rows from
                                         count on are zero
    """

    kind = Kind.NET
    body = [("cols", "<u2"), ("rows", "<u2"), ("first", "<u4"), ("count", "<u2"), ("asleep", "u1"),
            ("width", "<f8"), ("height", "<f8"), ("offset", "<i2", (NET_CHUNK_KNOTS, 3))]

    @staticmethod
    def check(rec):
        cols, rows, first, count = int(rec["cols"]), int(rec["rows"]), int(rec["first"]), int(rec["count"])
        _within("net.cols", cols, 2, NET_MAX_SIDE)
        _within("net.rows", rows, 2, NET_MAX_SIDE)
        _within("net.count", count, 1, NET_CHUNK_KNOTS)
        _within("net.first", first, 0, cols * rows - count)
        _within("net.asleep", int(rec["asleep"]), 0, 1)
        for name, limit in (("width", 2 * MAX_POS_M), ("height", MAX_POS_M)):
            value = float(rec[name])
            if not 0.0 < value <= limit:
                raise OutOfRange(f"net.{name}: must be in (0, {limit:g}] m, got {value!r}")
        offset = rec["offset"]
        if int(offset[:count].min()) < -NET_MAX_OFFSET:
            raise OutOfRange(f"net.offset: {int(offset[:count].min())} is beyond -{NET_MAX_OFFSET} steps")
        if offset[count:].any():
            raise OutOfRange(f"net.offset: the rows from count ({count}) on must be zero")


class SceneRequest(_Spec):
    """scene_request, client -> server: send me the served scene (scene_part messages answer on
    the session). A client asks when it has no scene of the welcome's scene_digest (it keeps the
    scenes it was sent by digest); a request whose digest is not the served scene's, or beyond
    MAX_SCENE_REQUESTS in one session, counts as a bad message. Header tick: any.

    Layout, 32 bytes:
        off  size  field   type   unit / meaning
          0    24  header         HEADER_DTYPE
         24     8  digest  u1[8]  the welcome's scene_digest
    """

    kind = Kind.SCENE_REQUEST
    body = [("digest", "u1", (DIGEST_SIZE,))]
    tokens = ("digest",)


class ScenePart(_Spec):
    """scene_part, server -> client: one part of the served scene as a TOML document (UTF-8), the
    answer to a scene_request: parts 0 .. parts - 1 in order on the session, each carrying
    `size` bytes of the text. Join them, read the text as a scene file (every value written
    out, defaults too) and check that its digest is the welcome's. Header tick: the server's
    current tick.

    Layout, 4036 bytes:
        off  size  field   type      unit / meaning
          0    24  header            HEADER_DTYPE
         24     8  digest  u1[8]     the scene's digest, as in the welcome
         32     1  part    u1        this part's index, 0..parts - 1
         33     1  parts   u1        parts of the whole text, 1..16
         34     2  size    <u2       bytes of text in this part, 1..4000
         36  4000  text    u1[4000]  the part's bytes of the UTF-8 text (a character may be split
                                     between two parts); bytes from size on are zero
    """

    kind = Kind.SCENE_PART
    body = [("digest", "u1", (DIGEST_SIZE,)), ("part", "u1"), ("parts", "u1"), ("size", "<u2"),
            ("text", "u1", (SCENE_CHUNK,))]
    tokens = ("digest", "text")

    @staticmethod
    def check(rec):
        parts, size = int(rec["parts"]), int(rec["size"])
        _within("scene_part.parts", parts, 1, MAX_SCENE_PARTS)
        _within("scene_part.part", int(rec["part"]), 0, parts - 1)
        _within("scene_part.size", size, 1, SCENE_CHUNK)
        if rec["text"][size:].any():
            raise OutOfRange(f"scene_part.text: the bytes from size ({size}) on must be zero")


SPECS: dict[Kind, type[_Spec]] = {spec.kind: spec for spec in (Hello, Welcome, Reject, Input, Snapshot, Event,
                                                                 Heartbeat, Goodbye, Net, SceneRequest, ScenePart)}
SIZES = {kind: spec.dtype.itemsize for kind, spec in SPECS.items()}
