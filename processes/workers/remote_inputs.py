"""The physics worker's side of the gateway: the remote players' inputs, checked again and
applied before each tick, and the idle arm of each remote bat (RemoteInputs)."""
from __future__ import annotations

import math
from collections import Counter

import numpy as np

from engine.play.arm import brake_force
from engine.play.match import Match
from processes.network.wire import MAX_FORCE_N, MAX_TORQUE_NM
from processes.runtime.locks import LockTable
from processes.runtime.mailbox import Mailbox
from processes.runtime.shm import Arena
from processes.workers.layout import REMOTE_INPUT_DTYPE, RUN_LOCK_NAMES, write_ack
from processes.workers.options import RunOptions


def remote_input_refusal(bat: int, values, remote_bats: frozenset[int]) -> str | None:
    """Why the physics refuses a remote input (None: it is applied).

    The gateway posts only inputs that wire.decode accepted (finite, |force| <= MAX_FORCE_N,
    |torque| <= MAX_TORQUE_NM); these writes bypass
    engine.physics.world._check_inputs (they go straight into the bats' records), so the same rules
    are checked again here, where they are applied: a bad input is refused and counted by
    the caller, never applied.

    Args:
        bat: the mailbox entry's bat index. values: (6,) force N, torque N m, world frame.
        remote_bats: the indices of the scene's remote bats (the only ones a remote arm drives).

    Returns:
        "not_remote_bat", "non_finite", "force_out_of_range", "torque_out_of_range" or None.
    """
    if bat not in remote_bats:
        return "not_remote_bat"
    fx, fy, fz, tx, ty, tz = (float(v) for v in values)
    if not all(math.isfinite(v) for v in (fx, fy, fz, tx, ty, tz)):
        return "non_finite"
    if math.sqrt(fx * fx + fy * fy + fz * fz) > MAX_FORCE_N:  # a square that overflows to inf is beyond it too
        return "force_out_of_range"
    if math.sqrt(tx * tx + ty * ty + tz * tz) > MAX_TORQUE_NM:
        return "torque_out_of_range"
    return None


class RemoteInputs:
    """The remote players' inputs: drained from the gateway's locked mailbox before each tick,
    and the idle arm of each remote bat.

    Each input is checked again before it touches a bat (remote_input_refusal); a refused one is
    counted in `refused` by reason (reported with the worker's "done") and its seq is not
    acknowledged. An input holds from the tick it is applied for hold_ticks (the gateway's
    input_hold_s of match time), unless another comes; then, and for a bat whose seat has had no
    input yet, the arm is idle: every tick, before the step, its force is the brake of
    engine.play.arm.brake_force from the bat's velocity at that tick (the law the client's
    prediction applies too). Computed here from the state being stepped, the brake has no delay
    whatever the load: a gateway posting it from the snapshots it saw braked with a delay that
    grew with the load, and a PD law with enough delay drives the bat instead of stopping it.
    """

    def __init__(self, arena: Arena, options: RunOptions, match: Match):
        self.locks = LockTable(options.handles.lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
        self.box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], self.locks)
        self.inbox = np.zeros(self.box.capacity, REMOTE_INPUT_DTYPE)
        self.applied = arena["remote_applied"].array
        self.acks = arena["remote_acks"].array
        self.match = match
        self.remote_bats = frozenset(i for i, bat in enumerate(match.scene.bats) if bat.remote)
        self.refused: Counter[str] = Counter()
        self.hold_ticks = match.compiled.ticks(options.gateway.input_hold_s)
        # the tick from which each bat's arm is idle; 0: from the start (a restarted physics has
        # lost its players' holds: it brakes until their next input)
        self.idle_from = np.zeros(len(match.scene.bats), np.int64)
        self._idle = sorted(self.remote_bats)
        self._mass = [float(m) for m in match.model.bat_mass]
        self._brake = np.zeros(6)
        self.brake_ticks = 0  # ticks stepped with an idle arm's brake, summed over the remote bats

    def apply(self, tick: int) -> None:
        """Before the step from `tick`: each new input holds from now on, in the bat's record
        (held between AI ticks) and in the match's inputs (which an AI control tick writes to
        every bat); an idle arm's bat gets its brake."""
        n = self.box.drain(self.inbox)
        bats = self.match.state.bats
        for k in range(n):
            bat = int(self.inbox[k]["bat"])
            values = self.inbox[k]["inputs"]
            reason = remote_input_refusal(bat, values, self.remote_bats)
            if reason is not None:
                self.refused[reason] += 1
                continue
            self.match.inputs[bat] = values
            bats[bat]["force"] = values[0:3]
            bats[bat]["torque"] = values[3:6]
            self.applied[bat] = self.inbox[k]["seq"]
            self.idle_from[bat] = tick + self.hold_ticks
        for bat in self._idle:
            if tick >= self.idle_from[bat]:
                brake = brake_force(self._mass[bat], bats[bat]["vel"], self._brake)
                self.match.inputs[bat] = brake
                bats[bat]["force"] = brake[0:3]
                bats[bat]["torque"] = brake[3:6]
                self.brake_ticks += 1

    def publish_ack(self, tick: int) -> None:
        """Before the snapshot of `tick` is published: the seqs it acknowledges (the inputs applied
        so far, none of the next tick's), for the gateway to pair with that snapshot."""
        write_ack(self.acks, tick, self.applied)

    def close(self) -> None:
        del self.applied, self.acks, self.box
        self.locks.close()
