"""What a speculating physics worker (processes.workers.speculation) publishes beside each
snapshot so that a restarted one can go on from it: the cut.

A snapshot of a speculating run holds only a state that every run before it confirms, but the
workers around it have gone on: the net has stepped runs past it and the AI has decided at
turns past it, on guesses. The cut says where they are to go back to: how many runs near the
net the physics had posted before the snapshot's tick (the net goes back to its state after
the last of them), the AI driver's turns in flight then (engine.play.match.Match's plans in
effect and processes.workers.ai_driver.AIDriver.checkpoint: the turns posted since are taken
back, as a go-back takes them).

Two rows, written in turn, each before the snapshot it goes with: the row of the snapshot
published last is never the one being written, so a physics killed while writing leaves the
cut of the snapshot it did publish. A row's tick is written last (-1 while it is written).
"""
from __future__ import annotations

import pickle

import numpy as np

CUT_BYTES = 1 << 13  # the AI driver's turns in flight: a decision delay's worth of (tick, turn) pairs
CUT_DTYPE = np.dtype([("tick", "<i8"), ("runs", "<i8"), ("size", "<i8"), ("data", "u1", (CUT_BYTES,))])
CUT_ROWS = 2


class Cuts:
    """The `spec_cut` block's two rows (CUT_DTYPE), for the physics that writes them and the one
    restarted that reads them."""

    def __init__(self, rows: np.ndarray):
        self.rows = rows
        self.next = 0  # the row written next

    def write(self, tick: int, runs: int, arm: np.ndarray, driver_checkpoint) -> None:
        """The cut of the snapshot at `tick` about to be published: `runs` runs posted before it, the
        plans in effect and the driver's checkpoint (None: no AI) there."""
        # the plans' bytes: pickling an array costs several times more than its few hundred bytes
        data = pickle.dumps((arm.tobytes(), arm.dtype.str, arm.shape, driver_checkpoint), protocol=pickle.HIGHEST_PROTOCOL)
        if len(data) > CUT_BYTES:
            raise RuntimeError(f"speculation: the cut at tick {tick} takes {len(data)} bytes, above CUT_BYTES = "
                               f"{CUT_BYTES}")
        row = self.rows[self.next]
        row["tick"] = -1
        row["runs"] = runs
        row["size"] = len(data)
        row["data"][:len(data)] = np.frombuffer(data, np.uint8)
        row["tick"] = tick
        self.next = 1 - self.next

    def read(self, tick: int) -> tuple[int, np.ndarray, object]:
        """The cut of the snapshot at `tick` (the one a restarted physics resumes from): (runs, the
        plans in effect, the driver's checkpoint); the row after it is the one written next."""
        for k in range(CUT_ROWS):
            row = self.rows[k]
            if int(row["tick"]) == tick:
                plans, dtype, shape, driver_checkpoint = pickle.loads(row["data"][:int(row["size"])].tobytes())
                self.next = 1 - k
                return int(row["runs"]), np.frombuffer(plans, dtype).reshape(shape), driver_checkpoint
        raise RuntimeError(f"speculation: no cut for the snapshot at tick {tick} (the cuts are at ticks "
                           f"{[int(r) for r in self.rows['tick']]})")
