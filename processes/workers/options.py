"""What the supervisor tells every worker of a run, each default stated once: the run's
configuration (RunOptions), the IPC handles of its shared turns and locks (RunHandles), and,
for tests only, what to do wrong (processes.runtime.faults.FaultPlan)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from engine.play.players import DEFAULT_BUDGET_S

if TYPE_CHECKING:  # for the annotations only: the options module stays cheap to import
    from multiprocessing.synchronize import Event

    from processes.network.server.config import GatewayConfig
    from processes.runtime.faults import FaultPlan
    from processes.runtime.handoff import Baton, TurnQueue

# A served match waits this long for its remote players to take their seats, then starts.
PLAYERS_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class RunHandles:
    """The run's IPC objects a worker attaches to (made by processes.workers.layout.build_layout).

    Attributes:
        ai_queue, net_baton: the AI's turns (processes.runtime.handoff.TurnQueue) and the net's
            turns' baton (None: no such worker). net_queue: a speculating run's queue of the
            net's runs (RunOptions.speculate; else None). lock_path: the run's lock table (a run with a gateway).
        start_event: set by the gateway while every remote seat is held (a run with a gateway).
    """

    ai_queue: TurnQueue | None = None
    net_baton: Baton | None = None
    lock_path: str | None = None
    start_event: Event | None = None
    net_queue: TurnQueue | None = None


@dataclass(frozen=True)
class RunOptions:
    """One worker's options (pickled to it once, at its start).

    Attributes:
        ticks: ticks the run reaches. mode: "lockstep" or "realtime".
        trace: keep every tick's physics snapshot in the "trace" array.
        seed: the match's seed. frame_every: keep a snapshot every this many ticks (replays), 0: none.
        players_timeout: s, a served match waits this long for its remote players, then starts.
        gateway: the gateway's configuration, for a scene with the effect "remote".
        handoff_s: s, the physics waits this long for the AI's or the net's answer to a turn,
            then gives the turn again (a restarted worker takes it) and waits again.
        on_bot_error: "point" or "stop" (engine.play.match.Match). bot_budget_s: CPU s a bot's
            decision may take (engine.play.players).
        timeline_dir: a directory into which each worker writes its timeline at its end
            (processes.runtime.timeline: when it worked, waited and for whom), None: none kept.
        gate_ai_turns: the physics gives the AI a turn only at the control ticks where a player
            could decide (processes.workers.ai_driver.AIDriver), not at every one: for a run
            whose workers outnumber the cores, where a turn nobody needs costs another worker
            its CPU; with a core to itself the AI answers every turn and stays awake, so a
            decision is answered sooner (the supervisor decides).
        speculate: a lockstep match with a cloth net: the physics steps on past the ball's runs
            near the net before the net has answered them, as if the net touched none, and
            goes back to the touch where it did (processes.workers.speculation); a run that
            keeps traces, frames or has remote players or a bot in a seat is refused.
        handles: the run's IPC objects (RunHandles).
        faults: tests and `pingpong stress` only: what this incarnation of this worker does
            wrong (FaultPlan); None in every other run.
    """

    ticks: int
    mode: str = "lockstep"
    trace: bool = False
    seed: int = 0
    frame_every: int = 0
    players_timeout: float = PLAYERS_TIMEOUT_S
    gateway: GatewayConfig | None = None
    handoff_s: float = 1.0
    on_bot_error: str = "point"
    bot_budget_s: float | None = DEFAULT_BUDGET_S
    timeline_dir: str | None = None
    gate_ai_turns: bool = False
    speculate: bool = False
    handles: RunHandles = field(default_factory=RunHandles)
    faults: FaultPlan | None = None

    def __post_init__(self):
        if self.mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {self.mode!r}")


def speculation_refusal(scene, kinds: list[str], mode: str, trace: bool, frame_every: int) -> str | None:
    """Why a run cannot speculate (RunOptions.speculate), or None: it can. scene: the run's
    engine.physics.scene.Scene; kinds: its workers."""
    from engine.physics.scene import is_bot_spec

    if scene.match is None or "net" not in kinds:
        return f"scene {scene.name!r} is not a match with a cloth net: there is no net's answer to step past"
    if mode != "lockstep":
        return "a realtime run shows each tick as it is stepped; only a lockstep run speculates"
    if trace or frame_every:
        return "traces and replay frames keep every tick as it is stepped; leave speculate off to keep them"
    if "remote" in scene.effects:
        return "remote players see each tick as it is stepped; leave speculate off to serve a match"
    bots = [bat.skill for bat in scene.bats if bat.skill is not None and is_bot_spec(bat.skill)]
    if bots:
        return f"a bot's own objects cannot be taken back to an earlier decision ({', '.join(bots)}); use AI profiles"
    return None
