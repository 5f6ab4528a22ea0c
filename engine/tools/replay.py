"""Replay files: a versioned record of a match in the engine's own structured dtypes.

The file is a numpy .npz archive (zip of .npy arrays, each carrying its dtype):
- `header`: UTF-8 JSON: magic, format version, scene name and source text, seed, tick length,
  frame spacing, and the description (`descr`) of every dtype below;
- `frames`: physics_snapshot_dtype records every `frame_every` ticks (ball, bats, world, rally);
- `events`: CONTACT_DTYPE, every contact of the ball;
- `points`: POINT_DTYPE, every decided rally with its reason.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.physics.dtypes import CONTACT_DTYPE, POINT_DTYPE

MAGIC = "pingpong-replay"
VERSION = 1


class ReplayError(ValueError):
    """A file that is not a readable replay; the message says what is wrong."""


@dataclass
class Replay:
    header: dict
    frames: np.ndarray
    events: np.ndarray
    points: np.ndarray


def write(path: str | Path, *, scene_name: str, scene_text: str, seed: int, dt: float, frame_every: int,
          frames: np.ndarray, events: np.ndarray, points: np.ndarray, summary: dict) -> None:
    header = {
        "magic": MAGIC,
        "version": VERSION,
        "scene": scene_name,
        "scene_toml": scene_text,
        "seed": seed,
        "dt": dt,
        "frame_every": frame_every,
        "dtypes": {"frames": frames.dtype.descr, "events": events.dtype.descr, "points": points.dtype.descr},
        "summary": summary,
    }
    blob = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with open(path, "wb") as f:
        np.savez_compressed(f, header=blob, frames=frames, events=events.astype(CONTACT_DTYPE),
                            points=points.astype(POINT_DTYPE))


def read(path: str | Path) -> Replay:
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(bytes(data["header"]).decode())
            arrays = {k: data[k] for k in ("frames", "events", "points")}
    except FileNotFoundError:
        raise ReplayError(f"{path}: no such file") from None
    except (OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise ReplayError(f"{path}: not a pingpong replay ({exc})") from None
    if header.get("magic") != MAGIC:
        raise ReplayError(f"{path}: not a pingpong replay (magic {header.get('magic')!r})")
    if header.get("version") != VERSION:
        raise ReplayError(f"{path}: replay format version {header.get('version')}, this pingpong reads {VERSION}")
    return Replay(header, arrays["frames"], arrays["events"], arrays["points"])
