"""Client-side prediction of the server's snapshots (a player).

A player's client runs the engine itself (engine.physics.world.step, the kernel the server runs) from
the last authoritative snapshot, applying its own inputs at the ticks it stamped them with,
so the ball and its own bat move on its screen (and under its controller) at once instead of a
round trip later. On each snapshot of tick T acknowledging input seq s it reconciles: rewind to
the snapshot's state at T, keep only its inputs after s, and replay them up to the tick it was
predicting. Before rewinding it compares what it had predicted for tick T with the snapshot:
those position errors of the ball and of its own bat are the prediction error statistics.

What the client cannot know, it predicts as follows, and the statistics measure the cost:
- the opponent's bat coasts (its force is not on the wire): the ball meets it where it drifts;
- an input holds from the tick it was stamped with (the server applies it on arrival, about a
  one-way trip later), and an input not yet acknowledged at T holds from T at the earliest;
  it holds for the wire's INPUT_HOLD_S at most (then the server's idle arm brakes the bat
  every tick, engine.play.arm.brake_force), counted in ticks from its stamp (the server's physics
  counts from the tick it applied it);
- the ball at a snapshot is in flight (the wire has no support flag: a resting ball settles
  again within a tick);
- a new rally's toss moves the ball where no physics takes it: a snapshot whose rally differs
  from the previous snapshot's is not scored (counted as `tosses`).
"""
from __future__ import annotations

from collections import deque

import numpy as np

from engine.physics.compiled import compile_scene
from engine.physics.world import SimulationError, new_events, step
from engine.play.arm import brake_force
from processes.network.wire import INPUT_HOLD_S, Slot

MAX_AHEAD_TICKS = 500  # a prediction runs at most this far past the last snapshot (0.5 s at 1 kHz)
CLOCK_WINDOW = 16  # snapshots over which the least-delayed one sets the server's clock (short: a
# server slower than realtime must pull the estimate back within ~0.16 s)


class ErrorStats:
    """Samples of a distance in metres; summary in millimetres."""

    def __init__(self):
        self.samples: list[float] = []

    def add(self, metres: float) -> None:
        self.samples.append(float(metres))

    def summary(self) -> dict:
        """n, mean_mm, p50_mm, p99_mm, max_mm (None without samples)."""
        if not self.samples:
            return {"n": 0, "mean_mm": None, "p50_mm": None, "p99_mm": None, "max_mm": None}
        mm = np.asarray(self.samples) * 1000.0
        return {"n": len(mm), "mean_mm": float(mm.mean()), "p50_mm": float(np.percentile(mm, 50)),
                "p99_mm": float(np.percentile(mm, 99)), "max_mm": float(mm.max())}


class ServerClock:
    """The server's tick now, estimated from the snapshots' ticks and arrival times.

    Each snapshot of tick T arriving at wall time w says the server was at T at w minus its
    one-way delay; the least-delayed of the last CLOCK_WINDOW snapshots sets the offset (late
    ones would make the clock lag). Until the first snapshot there is no estimate (None).
    """

    def __init__(self, dt: float):
        self.dt = dt
        self._offsets: deque[float] = deque(maxlen=CLOCK_WINDOW)  # s: T * dt - arrival

    def observe(self, tick: int, arrival: float) -> None:
        self._offsets.append(tick * self.dt - arrival)

    def tick_at(self, wall: float) -> float | None:
        """Fractional server tick at wall time `wall` (s, the clock the arrivals were given in)."""
        if not self._offsets:
            return None
        return (wall + max(self._offsets)) / self.dt


class RoundTrip:
    """The round trip from sending an input to the first snapshot that acknowledges it.

    The least of the last `window` samples: each sample is the true round trip plus the wait
    for the physics' next tick and the gateway's next snapshot (up to one snapshot interval),
    which the least of many removes. A player stamps its inputs that far ahead of the server's
    estimated present (the clock lags the server by the one-way trip, the input takes another).
    """

    def __init__(self, window: int = 32):
        self._sent: deque[tuple[int, float]] = deque(maxlen=4096)  # (seq, wall s) awaiting an ack
        self._samples: deque[float] = deque(maxlen=window)
        self._acked = 0

    def sent(self, seq: int, wall: float) -> None:
        self._sent.append((seq, wall))

    def acked(self, seq: int, wall: float) -> None:
        """A snapshot arriving at `wall` acknowledges inputs up to `seq`."""
        if seq <= self._acked or not self._sent or seq > self._sent[-1][0]:
            return  # old news, or a seq we never sent (the previous session's at this seat)
        self._acked = seq
        newest = None
        while self._sent and self._sent[0][0] <= seq:
            newest = self._sent.popleft()
        if newest is not None and newest[0] == seq:
            self._samples.append(wall - newest[1])

    @property
    def seconds(self) -> float:
        """The estimate in s (0 before the first sample)."""
        return min(self._samples) if self._samples else 0.0

    def summary(self) -> dict:
        return {"n": len(self._samples), "min_ms": self.seconds * 1000.0,
                "median_ms": float(np.median(self._samples)) * 1000.0 if self._samples else None}


class Predictor:
    """The player's prediction of the ball and its own bat, reconciled on every snapshot.

    Args:
        scene: the served scene (engine.physics.scene.Scene, or compiled:
            engine.physics.compiled.CompiledScene): the same physics as the server.
        slot: our seat (Slot.A or Slot.B); its bat is the one our inputs drive.
        history: ticks of predictions kept to compare with the snapshots that arrive later.
    """

    def __init__(self, scene, slot: Slot, history: int = 2048, input_hold_s: float | None = None):
        if slot not in (Slot.A, Slot.B):
            raise ValueError(f"a predictor drives a player's bat: slot must be A or B, got {slot!r}")
        compiled = compile_scene(scene)
        self.model = compiled.model
        self.state = compiled.initial_state()
        self.events = new_events()
        self.player = slot.bat
        self.dt = self.model.dt
        self.tick: int | None = None  # the tick the predicted state is at; None before a snapshot
        self._sent: list[tuple[int, int, np.ndarray]] = []  # (seq, tick, inputs) not yet acknowledged
        self._held = np.zeros(6)  # our input in effect at the base snapshot (the acknowledged one)
        self._held_from = 0  # the tick it was stamped with
        self._input_from = 0  # the stamp of the input in effect while predicting
        self.hold_ticks = compiled.ticks(INPUT_HOLD_S if input_hold_s is None else input_hold_s)
        self._bat_mass = float(self.model.bat_mass[slot.bat])
        self._brake = np.zeros(6)
        self._next_input = 0  # index into _sent of the next input to take effect while predicting
        self._max_seq = 0  # the highest seq we sent
        self._base_tick = -1
        self._base_rally: int | None = None
        self._hist_tick = np.full(history, -1, np.int64)
        self._hist = np.zeros((history, 6))  # ball pos, own bat pos after each predicted tick
        self.ball_error = ErrorStats()
        self.bat_error = ErrorStats()
        # The baseline measured in the same run: a client without prediction shows the last
        # snapshot until the next arrives; its error at tick T is |state(previous) - state(T)|.
        self.ball_stale = ErrorStats()
        self.bat_stale = ErrorStats()
        self._base_pos = np.zeros(6)  # ball pos, own bat pos of the base snapshot
        self.counts = {"snapshots": 0, "scored": 0, "tosses": 0, "late": 0, "replayed_ticks": 0,
                       "predicted_ticks": 0, "engine_errors": 0}
        self.step(0.0)  # load (or compile) the kernels now, not at the first snapshot

    def step(self, dt: float | None = None) -> None:
        """One engine tick of the predicted state (dt=0: no change, loads the kernels)."""
        step(self.model, self.state, None, self.events, dt=dt)

    # --- inputs -----------------------------------------------------------------------------
    def record_input(self, seq: int, tick: int, inputs) -> None:
        """An input we sent: seq of its header, the tick it holds from, (6,) force N, torque N m."""
        self._sent.append((int(seq), int(tick), np.array(inputs, dtype=np.float64)))
        self._max_seq = max(self._max_seq, int(seq))

    @property
    def pending(self) -> int:
        """Inputs sent and not acknowledged by the last snapshot."""
        return len(self._sent)

    # --- reconciliation -------------------------------------------------------------------------
    def reconcile(self, snapshot) -> tuple[float, float] | None:
        """Take the server's snapshot: score the prediction for its tick, rewind, replay.

        Returns:
            (ball error m, own bat error m) at the snapshot's tick, or None when not scored (the
            first snapshot, a snapshot older than the base, or a new rally's toss).
        """
        tick = snapshot.tick
        self.counts["snapshots"] += 1
        if tick <= self._base_tick:
            self.counts["late"] += 1  # reordered or repeated: the base is newer already
            return None
        errors = None
        target = self.tick
        if self.tick is not None:
            if self.tick < tick:
                self.advance_to(tick)  # what we would have shown at T, with what we knew before it
            if snapshot["rally"] != self._base_rally:
                self.counts["tosses"] += 1
            elif self._hist_tick[tick % len(self._hist_tick)] == tick:
                row = self._hist[tick % len(self._hist_tick)]
                errors = (float(np.linalg.norm(row[0:3] - snapshot["ball_pos"])),
                          float(np.linalg.norm(row[3:6] - snapshot["bat_pos"][self.player])))
                self.ball_error.add(errors[0])
                self.bat_error.add(errors[1])
                self.ball_stale.add(float(np.linalg.norm(self._base_pos[0:3] - snapshot["ball_pos"])))
                self.bat_stale.add(float(np.linalg.norm(self._base_pos[3:6] - snapshot["bat_pos"][self.player])))
                self.counts["scored"] += 1
        ack = int(snapshot["input_seq"][self.player])
        if ack > self._max_seq:
            ack = 0  # a seq we never sent: the previous session's at this seat (we rejoined), not ours
        keep = []
        for seq, at, inputs in self._sent:
            if seq <= ack:
                self._held, self._held_from = inputs, at  # the last acknowledged input: in effect at T
            else:
                keep.append((seq, at, inputs))
        self._sent = keep
        self._load(snapshot)
        self._base_tick, self._base_rally = tick, snapshot["rally"]
        self._base_pos[0:3], self._base_pos[3:6] = snapshot["ball_pos"], snapshot["bat_pos"][self.player]
        self.tick = tick
        self._next_input = 0
        self._input_from = self._held_from
        self._record(tick)
        if target is not None and target > tick:
            before = self.counts["predicted_ticks"]
            self.advance_to(target)
            self.counts["replayed_ticks"] += self.counts["predicted_ticks"] - before
        return errors

    def _load(self, snapshot) -> None:
        """The predicted state := the snapshot (our bat's input: the acknowledged one)."""
        state = self.state
        ball = state.ball[0]
        ball["pos"], ball["vel"], ball["spin"] = snapshot["ball_pos"], snapshot["ball_vel"], snapshot["ball_spin"]
        bats = state.bats
        bats["pos"], bats["quat"] = snapshot["bat_pos"], snapshot["bat_quat"]
        bats["vel"], bats["ang_vel"] = snapshot["bat_vel"], snapshot["bat_ang_vel"]
        bats["force"], bats["torque"] = 0.0, 0.0  # the opponent's arm: unknown, it coasts
        bats[self.player]["force"], bats[self.player]["torque"] = self._held[0:3], self._held[3:6]
        world = state.world[0]
        world["tick"], world["time"] = snapshot.tick, snapshot.tick * self.dt
        world["ball_support"] = 0

    # --- prediction -------------------------------------------------------------------------
    def advance_to(self, tick: int) -> int:
        """Predict up to `tick` (at most MAX_AHEAD_TICKS past the base); returns ticks stepped."""
        if self.tick is None:
            return 0
        tick = min(int(tick), self._base_tick + MAX_AHEAD_TICKS)
        bat = self.state.bats[self.player]
        done = 0
        while self.tick < tick:
            while self._next_input < len(self._sent) and max(self._sent[self._next_input][1], self._base_tick) <= self.tick:
                _, at, inputs = self._sent[self._next_input]
                bat["force"], bat["torque"] = inputs[0:3], inputs[3:6]
                self._input_from = max(at, self._base_tick)
                self._next_input += 1
            if self.tick - self._input_from >= self.hold_ticks:  # expired: the server's idle arm brakes
                brake_force(self._bat_mass, bat["vel"], self._brake)
                bat["force"], bat["torque"] = self._brake[0:3], self._brake[3:6]
            try:
                self.step()
            except SimulationError:
                self.counts["engine_errors"] += 1  # e.g. a coasting bat traps the ball: wait for the server
                return done
            self.tick += 1
            done += 1
            self._record(self.tick)
        self.counts["predicted_ticks"] += done
        return done

    def _record(self, tick: int) -> None:
        i = tick % len(self._hist_tick)
        self._hist_tick[i] = tick
        self._hist[i, 0:3] = self.state.ball[0]["pos"]
        self._hist[i, 3:6] = self.state.bats[self.player]["pos"]

    @property
    def stale(self) -> bool:
        """The prediction reached MAX_AHEAD_TICKS past the last snapshot: it no longer says
        where things are (the server fell silent, or its snapshots stopped)."""
        return self.tick is None or self.tick >= self._base_tick + MAX_AHEAD_TICKS

    @property
    def ball(self):
        """The predicted ball: one BALL_DTYPE record (pos, vel, spin)."""
        return self.state.ball[0]

    @property
    def bat(self):
        """Our predicted bat: one BAT_DTYPE record."""
        return self.state.bats[self.player]

    def stats(self) -> dict:
        """Prediction errors at the snapshots' ticks (mm), the same for showing the previous
        snapshot instead (`without_prediction`, the baseline), and the counts above."""
        return {"ball": self.ball_error.summary(), "bat": self.bat_error.summary(),
                "without_prediction": {"ball": self.ball_stale.summary(), "bat": self.bat_stale.summary()},
                **self.counts}


__all__ = ["ErrorStats", "ServerClock", "RoundTrip", "Predictor", "MAX_AHEAD_TICKS"]
