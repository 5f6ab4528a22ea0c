"""The wire's validating decoder and encoder: bytes to a Message and back, nothing unchecked."""
from __future__ import annotations

import enum
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.play.rules import REASONS
from processes.network.wire.checks import (BadEnum, BadFlags, BadMagic, BadText, BadVersion, NonFinite, OutOfRange,
                                           TooLong, TooShort, UnknownType, WireError, _text)
from processes.network.wire.messages import (HEADER_DTYPE, HEADER_SIZE, MAGIC, MAX_FORCE_N, MAX_REALTIME_FACTOR,
                                             MAX_TORQUE_NM, PROTOCOL_VERSION, SPECS, InputMode, Kind, _Spec)

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
        """Plain JSON-able values: enums by name, tokens in hex, arrays as lists; an event's
        reason also by name (reason_name, engine.play.rules.REASONS)."""
        out: dict[str, Any] = {"kind": self.kind.name.lower(), "seq": self.seq, "tick": self.tick, "flags": self.flags}
        for name, value in self.fields.items():
            if isinstance(value, enum.IntEnum):
                value = value.name.lower()
            elif isinstance(value, bytes):
                value = value.hex()
            elif isinstance(value, np.ndarray):
                value = value.tolist()
            out[name] = value
        if self.kind == Kind.EVENT:
            out["reason_name"] = REASONS[self.fields["reason"]].value
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
    if array.dtype.kind == "O":
        fits = all(info.min <= int(v) <= info.max for v in array.flat)
    else:  # vectorised: a net message's 1920 offsets
        fits = array.size == 0 or (info.min <= int(array.min()) and int(array.max()) <= info.max)
    if not fits:
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
def snapshot_from_physics(record, *, seq: int, input_seq=(0, 0), realtime_factor: float = 1.0) -> bytes:
    """A snapshot message from one engine.physics.dtypes.physics_snapshot_dtype(2) record (and the
    realtime factor its sender measured; a replay's is 1). The wire numbers rallies from 1 (the
    first is tossed as the match begins); the engine's counter, from 0, counts those decided."""
    ball, bats, world, rally = record["ball"], record["bats"], record["world"], record["rally"]
    return encode(Kind.SNAPSHOT, seq=seq, tick=int(world["tick"]), ball_pos=ball["pos"], ball_vel=ball["vel"],
                  ball_spin=ball["spin"], bat_pos=bats["pos"], bat_quat=bats["quat"], bat_vel=bats["vel"],
                  bat_ang_vel=bats["ang_vel"], input_seq=np.asarray(input_seq, np.uint64),
                  rally=int(rally["rally"]) + 1, score=rally["score"], games_won=rally["games_won"],
                  phase=int(rally["phase"]), server=int(rally["server"]), striker=int(rally["striker"]),
                  winner=int(rally["winner"]), realtime_factor=min(max(realtime_factor, 0.0), MAX_REALTIME_FACTOR))


# A norm within this factor of its limit is left to decode: its sum of squares may round the
# other way than decode's dot product, and the check must never pass what decode refuses.
_NORM_MARGIN = 1.0 - 1e-9


def own_force_inputs(datas: list[bytes], slot: int) -> np.ndarray:
    """Which of `datas` decode would accept as force-mode inputs of bat `slot`, all checked in
    one vectorised pass: a bool per message, True only if decode(data) succeeds and gives an
    input with that slot and mode force (False says nothing about why: decode names it).

    For the gateway's coalescing: of one player's inputs that arrived together only the newest
    is decoded and posted; the rest are checked here, at a fraction of a decode's cost each, so
    a malformed one among them is still found (and then decoded, to count its reason).
    """
    spec = SPECS[Kind.INPUT]
    size = spec.dtype.itemsize
    ok = np.fromiter((len(d) == size for d in datas), bool, len(datas))
    recs = np.frombuffer(b"".join(d if good else bytes(size) for d, good in zip(datas, ok)), spec.dtype)
    with np.errstate(all="ignore"):  # inf/nan compare False below; overflowing squares are inf
        force, torque = recs["force"], recs["torque"]
        ok &= ((recs["magic"] == MAGIC) & (recs["version"] == PROTOCOL_VERSION) & (recs["kind"] == Kind.INPUT)
               & (recs["flags"] == 0) & (recs["tick"] >= 0) & (recs["slot"] == slot)
               & (recs["mode"] == InputMode.FORCE)
               & (np.abs(force) <= MAX_FORCE_N).all(axis=1) & (np.abs(torque) <= MAX_TORQUE_NM).all(axis=1)
               & (np.sqrt((force * force).sum(axis=1)) <= MAX_FORCE_N * _NORM_MARGIN)
               & (np.sqrt((torque * torque).sum(axis=1)) <= MAX_TORQUE_NM * _NORM_MARGIN)
               & (recs["target_pos"] == 0.0).all(axis=1) & (recs["target_quat"] == 0.0).all(axis=1))
    return ok


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
