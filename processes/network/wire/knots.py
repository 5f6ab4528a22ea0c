"""The cloth net's knots on the wire: the rest grid, knots to net messages and back (wire.Net)."""
from __future__ import annotations

import numpy as np

from processes.network.wire.codec import Message, encode
from processes.network.wire.messages import NET_CHUNK_KNOTS, NET_MAX_OFFSET, NET_STEP_M, Kind


def net_rest(cols: int, rows: int, width: float, height: float) -> np.ndarray:
    """(cols * rows, 3) m: the rest grid a net message's offsets are from (wire.Net's docstring),
    knot = row * cols + col, in the plane x = 0; net_kernel.topology.build_topology's knot_pos."""
    col = np.tile(np.arange(cols), rows)
    row = np.repeat(np.arange(rows), cols)
    rest = np.zeros((cols * rows, 3))
    rest[:, 1] = -width / 2 + col * (width / (cols - 1))
    rest[:, 2] = row * (height / (rows - 1))
    return rest


def net_messages(knot_pos, *, cols: int, rows: int, width: float, height: float, asleep: bool,
                 tick: int) -> tuple[list[bytes], int]:
    """The net messages of one state: knot_pos (cols * rows, 3) m, world frame.

    Returns:
        (the messages, in knot order, ceil(cols * rows / NET_CHUNK_KNOTS) of them; how many
        coordinates were clamped to the wire's range, +-NET_MAX_OFFSET steps).

    Raises:
        WireError: a grid the wire cannot carry (a side beyond NET_MAX_SIDE, a width out of range).
    """
    pos = np.asarray(knot_pos, dtype=np.float64)
    steps = np.rint((pos - net_rest(cols, rows, width, height)) / NET_STEP_M)
    clamped = int(np.count_nonzero(~(np.abs(steps) <= NET_MAX_OFFSET)))  # NaN counts as clamped
    steps = np.clip(np.nan_to_num(steps), -NET_MAX_OFFSET, NET_MAX_OFFSET).astype(np.int16)
    out = []
    offset = np.zeros((NET_CHUNK_KNOTS, 3), np.int16)
    for first in range(0, cols * rows, NET_CHUNK_KNOTS):
        chunk = steps[first:first + NET_CHUNK_KNOTS]
        offset[:] = 0
        offset[:len(chunk)] = chunk
        out.append(encode(Kind.NET, tick=tick, cols=cols, rows=rows, first=first, count=len(chunk),
                          asleep=int(asleep), width=width, height=height, offset=offset))
    return out, clamped


def net_knots(message: Message, out: np.ndarray) -> None:
    """Write a decoded net message's knots into out (cols * rows, 3) m: rest + offset * NET_STEP_M."""
    first, count = message["first"], message["count"]
    cols, rows = message["cols"], message["rows"]
    rest = net_rest(cols, rows, message["width"], message["height"])[first:first + count]
    out[first:first + count] = rest + message["offset"][:count] * NET_STEP_M
