"""Why a wire message is refused: one WireError subclass per reason a gateway counts, and the checks
that raise them."""
from __future__ import annotations

import unicodedata

import numpy as np

QUAT_TOL = 1e-6  # a quaternion's norm must be within this of 1

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
