"""Keyboard play: keys from a terminal, a bat target they move, the arm controller that chases it.

Keys (from the player's own end, looking at the net):
    w / up arrow      target forward, towards the net      s / down arrow   back
    a / left arrow    target left                          d / right arrow  right
    r                 target up                            f                down
    space             a stroke: the target lunges STROKE_M towards the net for STROKE_S
    q / Ctrl-C        leave

The client never moves its bat: it turns the target into force and torque with the engine's own
arm controller (engine.play.arm.bat_control, the PD law with the arm's limits that the AI drives its
bat with), from the bat's predicted state, and sends those as inputs. A key source is either
the terminal (`TerminalKeys`, cbreak mode, restored on exit) or any iterable of key batches
(`IterableKeys`, what tests feed), so the same loop runs with and without a TTY.
"""
from __future__ import annotations

import os
import select
import termios
import tty

import numpy as np

from engine.play.ai import HALF_LENGTH, HALF_WIDTH, SKILLS, BatAI
from engine.play.arm import (CTL_D_ANGLE, CTL_HOLD, CTL_INERTIA, CTL_K_ANGLE, CTL_KD, CTL_KP, CTL_MASS, CTL_MAX_FORCE,
                             CTL_MAX_SPEED, CTL_MAX_TORQUE, CTL_N_SEGMENTS, CTL_NORMAL, CTL_SIZE, bat_control)
from processes.network.wire import Slot

STEP_M = 0.05  # target move per key press
STROKE_M = 0.30  # how far a stroke lunges forward
STROKE_S = 0.15  # and for how long
# The reach box of a player's target, from its own end line (m): a little over the table, well
# behind it, across the table's width and beyond, from table height down to up high.
REACH_IN_M, REACH_OUT_M = 0.5, 1.5
REACH_Y_M = 1.2
REACH_Z_M = (-0.1, 0.8)

_ESCAPES = {b"\x1b[A": "up", b"\x1b[B": "down", b"\x1b[C": "right", b"\x1b[D": "left",
            b"\x1bOA": "up", b"\x1bOB": "down", b"\x1bOC": "right", b"\x1bOD": "left"}
_LETTERS = {"w": "up", "s": "down", "a": "left", "d": "right", "r": "raise", "f": "lower", " ": "stroke",
            "q": "quit", "\x03": "quit"}
KEYS = ("up", "down", "left", "right", "raise", "lower", "stroke", "quit")


def parse_keys(data: bytes) -> tuple[list[str], bytes]:
    """Key names in `data` (terminal bytes) and the bytes of an escape sequence cut off at its
    end (to prepend to the next read). Unknown bytes and sequences are skipped."""
    keys: list[str] = []
    i = 0
    while i < len(data):
        if data[i] == 0x1B:
            chunk = data[i:i + 3]
            if chunk in _ESCAPES:
                keys.append(_ESCAPES[chunk])
                i += 3
                continue
            if len(chunk) < 3 and any(seq.startswith(chunk) for seq in _ESCAPES):
                return keys, data[i:]  # the rest of the sequence is in the next read
            i += 1  # a lone escape or a sequence we do not use
            continue
        name = _LETTERS.get(chr(data[i]).lower())
        if name is not None:
            keys.append(name)
        i += 1
    return keys, b""


class TerminalKeys:
    """Keys from a terminal file descriptor in cbreak mode (no line buffering, no echo);
    `with TerminalKeys(fd) as keys: keys.poll()`. The terminal's mode is restored on exit."""

    def __init__(self, fd: int):
        self.fd = fd
        self._saved = None
        self._rest = b""

    def __enter__(self) -> "TerminalKeys":
        self._saved = termios.tcgetattr(self.fd)
        tty.setcbreak(self.fd)
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
            self._saved = None

    def poll(self, timeout_s: float = 0.0) -> list[str]:
        """Keys pressed since the last poll (waits at most timeout_s for the first)."""
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if not ready:
            return []
        data = os.read(self.fd, 1024)
        if not data:
            return ["quit"]  # end of input: the terminal went away
        keys, self._rest = parse_keys(self._rest + data)
        return keys


class IterableKeys:
    """Keys from an iterable: each poll takes the next item (a key name or a list of them);
    once it is exhausted, polls return nothing."""

    def __init__(self, batches):
        self._it = iter(batches)

    def poll(self, timeout_s: float = 0.0) -> list[str]:
        try:
            batch = next(self._it)
        except StopIteration:
            return []
        batch = [batch] if isinstance(batch, str) else list(batch)
        unknown = [k for k in batch if k not in KEYS]
        if unknown:
            raise ValueError(f"unknown keys {unknown}; keys are {', '.join(KEYS)}")
        return batch


class KeyboardPilot:
    """A bat target moved by keys and the force and torque that drive our bat to it.

    Args:
        model: engine.physics.world.Model of the served scene. slot: our seat, A or B.
        skill: engine.play.ai.SKILLS name whose arm limits (force, torque, speed) apply.
    """

    def __init__(self, model, slot: Slot, skill: str = "pro"):
        if slot not in (Slot.A, Slot.B):
            raise ValueError(f"keyboard play drives a player's bat: slot must be A or B, got {slot!r}")
        self.player = slot.bat
        self.end_sign = -1 if self.player == 0 else 1
        # The AI's own arm: bat_control (PD with feed-forward, the skill's force, torque and speed
        # limits) holding the pose in its control array; the pose is the keys' aim, so the
        # keyboard drives the bat exactly as the AI's arm drives its bat between strokes.
        skill = SKILLS[skill]
        self.ctl = np.zeros(CTL_SIZE)
        self.ctl[[CTL_MASS, CTL_INERTIA, CTL_KP, CTL_KD, CTL_K_ANGLE, CTL_D_ANGLE]] = (
            float(model.bat_mass[self.player]), float(model.bat_inertia[self.player][0]), BatAI.KP, BatAI.KD,
            BatAI.K_ANGLE, BatAI.D_ANGLE)
        self.ctl[[CTL_MAX_FORCE, CTL_MAX_TORQUE, CTL_MAX_SPEED]] = skill.max_force_n, skill.max_torque_nm, skill.max_speed
        # start where the AI waits (BatAI.ready_pose): 40 cm behind the end line, face to the net
        self.target = np.array([self.end_sign * (HALF_LENGTH + 0.4), 0.0, 0.15])
        self.normal = np.array([-self.end_sign, 0.0, 0.0])
        self.stroke_until = -1.0
        self.out = np.zeros(6)
        self.presses = 0

    def press(self, key: str, now: float) -> None:
        """Move the target by one key (see the module's table); 'quit' is the caller's."""
        forward = -self.end_sign  # towards the net
        left = -self.end_sign  # facing +x (player A) the left is +y; facing -x it is -y
        moves = {"up": (forward * STEP_M, 0.0, 0.0), "down": (-forward * STEP_M, 0.0, 0.0),
                 "left": (0.0, left * STEP_M, 0.0), "right": (0.0, -left * STEP_M, 0.0),
                 "raise": (0.0, 0.0, STEP_M), "lower": (0.0, 0.0, -STEP_M)}
        if key == "stroke":
            self.stroke_until = now + STROKE_S
        elif key in moves:
            self.target = self._clamp(self.target + np.array(moves[key]))
        else:
            return
        self.presses += 1

    def aim_at(self, pos) -> None:
        """Move the target to `pos` (m, world frame; a pointer's point), kept in the reach box."""
        self.target = self._clamp(np.asarray(pos, dtype=np.float64))
        self.presses += 1

    def _clamp(self, target: np.ndarray) -> np.ndarray:
        depth = min(max(self.end_sign * target[0], HALF_LENGTH - REACH_IN_M), HALF_LENGTH + REACH_OUT_M)
        return np.array([self.end_sign * depth, min(max(target[1], -REACH_Y_M), REACH_Y_M),
                         min(max(target[2], REACH_Z_M[0]), REACH_Z_M[1])])

    def aim(self, now: float) -> np.ndarray:
        """Where the bat is driven to now: the target, lunged forward during a stroke."""
        if now < self.stroke_until:
            return self._clamp(self.target + np.array([-self.end_sign * STROKE_M, 0.0, 0.0]))
        return self.target

    def control(self, now: float, bat) -> np.ndarray:
        """(6,) force N and torque N m for our bat (one BAT_DTYPE record) towards the aim."""
        self.ctl[CTL_HOLD:CTL_HOLD + 3] = self.aim(now)
        self.ctl[CTL_NORMAL:CTL_NORMAL + 3] = self.normal
        self.ctl[CTL_N_SEGMENTS] = 0  # no path: hold the pose
        floats = np.frombuffer(bat, np.float64) if isinstance(bat, np.void) else np.ascontiguousarray(bat).view(np.float64)
        bat_control(now, floats, self.ctl, self.out)
        return self.out


# --- the terminal picture -------------------------------------------------------------------------
BOARD_COLUMNS, BOARD_ROWS = 61, 15  # top view, x across the screen, y up the screen
BOARD_X_M, BOARD_Y_M = 3.2, 1.5  # half extents shown


def top_view(ball_pos, bat_pos, target=None) -> list[str]:
    """A top view of the table as text rows: table '.', net '|', ball 'o', bats 'A' 'B', target '+'."""
    grid = [[" "] * BOARD_COLUMNS for _ in range(BOARD_ROWS)]

    def cell(x, y):
        c = int(round((x + BOARD_X_M) / (2 * BOARD_X_M) * (BOARD_COLUMNS - 1)))
        r = int(round((BOARD_Y_M - y) / (2 * BOARD_Y_M) * (BOARD_ROWS - 1)))
        return (r, c) if 0 <= r < BOARD_ROWS and 0 <= c < BOARD_COLUMNS else None

    for r in range(BOARD_ROWS):
        for c in range(BOARD_COLUMNS):
            x = c / (BOARD_COLUMNS - 1) * 2 * BOARD_X_M - BOARD_X_M
            y = BOARD_Y_M - r / (BOARD_ROWS - 1) * 2 * BOARD_Y_M
            if abs(x) <= HALF_LENGTH and abs(y) <= HALF_WIDTH:
                grid[r][c] = "."
    net_col = cell(0.0, 0.0)[1]
    for r in range(BOARD_ROWS):
        grid[r][net_col] = "|"
    marks = [(target, "+")] if target is not None else []
    marks += [(bat_pos[0], "A"), (bat_pos[1], "B"), (ball_pos, "o")]
    for pos, mark in marks:
        where = cell(float(pos[0]), float(pos[1]))
        if where is not None:
            grid[where[0]][where[1]] = mark
    return ["".join(row) for row in grid]


__all__ = ["parse_keys", "TerminalKeys", "IterableKeys", "KeyboardPilot", "top_view", "KEYS", "STEP_M",
           "STROKE_M", "STROKE_S"]
