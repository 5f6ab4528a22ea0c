"""A whole in-process run of a scene: ticks, contact events, bounce apexes, wall time."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.geometry import Body
from engine.physics.scene import Scene
from engine.physics.world import Model, State, build_model, copy_record, initial_state, new_events, step


@dataclass
class RunResult:
    """What a run produced. Heights are the ball's bottom above the playing surface, m."""

    scene: Scene
    ticks: int
    sim_seconds: float
    wall_seconds: float  # the ticks alone
    compile_seconds: float  # loading or compiling the kernels, before the first tick
    events: np.ndarray  # CONTACT_DTYPE, every impact in order
    bounce_heights_m: list[float] = field(default_factory=list)
    state: State | None = None
    trace: np.ndarray | None = None  # (ticks + 1,) physics snapshots, tick 0 first, if asked for

    def summary(self) -> dict:
        """JSON-ready summary."""
        counts: dict[str, int] = {}
        for body in self.events["body"]:
            name = Body(int(body)).name.lower()
            counts[name] = counts.get(name, 0) + 1
        return {
            "scene": self.scene.name,
            "integrator": self.scene.integrator,
            "dt": self.scene.dt,
            "ticks": self.ticks,
            "sim_seconds": self.sim_seconds,
            "wall_seconds": self.wall_seconds,
            "compile_seconds": self.compile_seconds,
            "realtime_factor": self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else None,
            "impacts": counts,
            "events": [
                {
                    "tick": int(ev["tick"]),
                    "time": float(ev["time"]),
                    "body": Body(int(ev["body"])).name.lower(),
                    "pos": [float(c) for c in ev["pos"]],
                    "normal_speed": float(ev["normal_speed"]),
                    "vel_out": [float(c) for c in ev["vel_out"]],
                    "spin_out": [float(c) for c in ev["spin_out"]],
                }
                for ev in self.events
            ],
            "bounce_heights_m": self.bounce_heights_m,
            "final_ball": {
                "pos": [float(c) for c in self.state.ball["pos"][0]],
                "vel": [float(c) for c in self.state.ball["vel"][0]],
                "spin": [float(c) for c in self.state.ball["spin"][0]],
            } if self.state is not None else None,
        }


def run(scene: Scene, ticks: int | None = None, model: Model | None = None, trace: bool = False) -> RunResult:
    """Run a scene in-process for `ticks` (default: its duration), tracking table-bounce apexes.

    An apex is where the ball's vertical velocity turns from up to down in flight after a table
    bounce; it is placed between ticks by the ballistic z + v_z^2 / (2 g), exact without drag
    and within (drag v_z^3) of the truth with it.
    """
    model = model or build_model(scene)
    state = initial_state(scene)
    n_ticks = scene.ticks if ticks is None else ticks
    events = new_events()
    collected: list[np.ndarray] = []
    heights: list[float] = []
    radius = float(model.ball_params[0])
    g = model.gravity or 0.0
    after_table_bounce = False
    z_prev = vz_prev = 0.0
    # A zero-length tick is an identity (tests/engine/test_flight.py); it loads or compiles the
    # kernels so that the wall time below measures simulation, not compilation.
    compile_start = time.perf_counter()
    step(model, state, None, events, dt=0.0)
    compile_seconds = time.perf_counter() - compile_start
    states = np.zeros(n_ticks + 1, physics_snapshot_dtype(len(scene.bats))) if trace else None
    if trace:
        copy_record(state.record, states, 0)
    start = time.perf_counter()
    for tick in range(n_ticks):
        n = step(model, state, None, events)
        if trace:
            copy_record(state.record, states, tick + 1)
        if n:
            collected.append(events[:n].copy())
            # A bounce starts a flight whose apex counts only if the last impact was the table.
            after_table_bounce = int(events[n - 1]["body"]) == Body.TABLE
        z = float(state.ball_flat[2])
        vz = float(state.ball_flat[5])
        in_flight = int(state.world[0]["ball_support"]) == 0
        if after_table_bounce and in_flight and n == 0 and vz_prev > 0.0 >= vz and g > 0.0:
            heights.append(z_prev + vz_prev * vz_prev / (2.0 * g) - radius)
            after_table_bounce = False
        z_prev, vz_prev = z, vz
    wall = time.perf_counter() - start
    all_events = np.concatenate(collected) if collected else events[:0].copy()
    return RunResult(scene=scene, ticks=n_ticks, sim_seconds=n_ticks * model.dt, wall_seconds=wall,
                     compile_seconds=compile_seconds, events=all_events, bounce_heights_m=heights, state=state, trace=states)
