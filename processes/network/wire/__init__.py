"""The wire protocol: every network message's byte layout, its encoder and its validating decoder.

Each message is one ZeroMQ frame holding one record of a numpy structured dtype: explicit
little-endian fields, packed (no padding; `itemsize` is the sum of the fields), fixed size per
message type. Every message starts with the same 24-byte header:

    off  size  field    type  unit / meaning
      0     4  magic    S4    b"PPNG", the same in every version
      4     2  version  <u2   PROTOCOL_VERSION (5); with magic, frozen for all versions
      6     1  kind     u1    Kind: 1 hello ... 11 scene_part
      7     1  flags    u1    no bits defined in version 5: a set bit is refused (bad_flags)
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
3 adds the net message (kind 9, wire.Net): a cloth net's knots for display, as 0.01 mm int16
offsets from the rest grid the message itself describes, in chunks of 640 knots (every message
keeps one fixed size and stays within the gateway's 4096-byte frame bound). Nothing else
changed, but a version-2 client would count each net message as an unknown type. 4 adds
snapshot.realtime_factor. 5 makes the served scene travel with the match: welcome.scene_digest
(the welcome grows to 166 bytes), and scene_request / scene_part (kinds 10 and 11), with which a
client that lacks the scene of that digest gets its TOML text from the server; before, a client
loaded a scene of the welcome's name from its own disk, so a served custom scene could not be
joined and a different local copy predicted with other physics unnoticed.

`decode(buf)` validates everything before any field is used (size exactly right for the type,
magic, version, type, flags, finite numbers, ranges, unit quaternions, enums, text) and returns
a `Message`; a bad buffer raises a `WireError` subclass whose `reason` a gateway counts
(`DropCounter`), and no other exception, whatever the bytes. `encode(kind, ...)` runs the same
validation on what it built, so a peer never sends what the other side would drop.

Floats go on the wire as float64, the engine's own bits: a client rewinds its prediction to the
snapshot's exact state, and a 334-byte snapshot at 60 Hz is 20 kB/s per spectator, so
quantisation would buy little and cost a documented error in every reconciliation. The net's
knots are the exception: 680 to 2944 knots in float64 would be 16 to 70 kB a message, and they
are only drawn, never predicted from (wire.Net says why 0.01 mm steps are harmless there).
"""
from processes.network.wire.checks import (QUAT_TOL, REASON_CODES, WIRE_ERRORS, BadEnum, BadFlags, BadMagic, BadText,
                                           BadVersion, NonFinite, OutOfRange, TooLong, TooShort, UnknownType,
                                           WireError)
from processes.network.wire.codec import DropCounter, Message, decode, encode, own_force_inputs, snapshot_from_physics
from processes.network.wire.knots import net_knots, net_messages, net_rest
from processes.network.wire.scenes import SceneAssembly, scene_parts
from processes.network.wire.messages import (DEFAULT_GRACE_S, DEFAULT_HEARTBEAT_S, DEFAULT_MAX_SPECTATORS,
                                             DEFAULT_SNAPSHOT_HZ, DEFAULT_SNDHWM, DEFAULT_TIMEOUT_S, DETAIL_SIZE,
                                             DIGEST_SIZE, MAX_SCENE_PARTS, MAX_SCENE_REQUESTS, SCENE_CHUNK,
                                             ScenePart, SceneRequest,
                                             Event, EventKind, Goodbye, GoodbyeReason, HEADER_DTYPE, HEADER_FIELDS,
                                             HEADER_SIZE, Heartbeat, Hello, INPUT_HOLD_S, Input, InputMode, Kind,
                                             MAGIC, MAX_BAD, MAX_BAT_ANG_VEL_RADS, MAX_BEST_OF, MAX_DT_S, MAX_FORCE_N,
                                             MAX_FRAME_BYTES, MAX_GAMES_WON, MAX_POS_M, MAX_REALTIME_FACTOR,
                                             MAX_SPEED_MS, MAX_SPIN_RADS, MAX_TORQUE_NM, NAME_SIZE, NET_CHUNK_KNOTS,
                                             NET_HZ, NET_MAX_OFFSET, NET_MAX_SIDE, NET_STEP_M, NO_TOKEN, Net,
                                             PROTOCOL_VERSION, Reject, RejectReason, Role, SERVER_SILENCE_BEATS,
                                             SIZES, SPECS, Slot, Snapshot, TOKEN_SIZE, Welcome)


__all__ = [
    "BadEnum", "BadFlags", "BadMagic", "BadText", "BadVersion", "DEFAULT_GRACE_S", "DEFAULT_HEARTBEAT_S",
    "DEFAULT_MAX_SPECTATORS", "DEFAULT_SNAPSHOT_HZ", "DEFAULT_SNDHWM", "DEFAULT_TIMEOUT_S", "DETAIL_SIZE",
    "DIGEST_SIZE", "DropCounter", "Event", "EventKind", "Goodbye", "GoodbyeReason", "HEADER_DTYPE", "HEADER_FIELDS",
    "HEADER_SIZE", "Heartbeat", "Hello", "INPUT_HOLD_S", "Input", "InputMode", "Kind", "MAGIC", "MAX_BAD",
    "MAX_BAT_ANG_VEL_RADS", "MAX_BEST_OF", "MAX_DT_S", "MAX_FORCE_N", "MAX_FRAME_BYTES", "MAX_GAMES_WON",
    "MAX_POS_M", "MAX_REALTIME_FACTOR", "MAX_SCENE_PARTS", "MAX_SCENE_REQUESTS", "MAX_SPEED_MS", "MAX_SPIN_RADS",
    "MAX_TORQUE_NM", "Message", "NAME_SIZE", "NET_CHUNK_KNOTS", "NET_HZ", "NET_MAX_OFFSET", "NET_MAX_SIDE",
    "NET_STEP_M", "NO_TOKEN", "Net", "NonFinite", "OutOfRange", "PROTOCOL_VERSION", "QUAT_TOL", "REASON_CODES",
    "Reject", "RejectReason", "Role", "SCENE_CHUNK", "SERVER_SILENCE_BEATS", "SIZES", "SPECS", "SceneAssembly",
    "ScenePart", "SceneRequest", "Slot", "Snapshot", "TOKEN_SIZE", "TooLong", "TooShort", "UnknownType",
    "WIRE_ERRORS", "Welcome", "WireError", "decode", "encode", "net_knots", "net_messages",
    "net_rest", "own_force_inputs", "scene_parts", "snapshot_from_physics"
]
