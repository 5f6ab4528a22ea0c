"""RunOptions: what the supervisor tells every worker of a run, with each default stated once."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from engine.players import DEFAULT_BUDGET_S
from processes.runtime.control import CRASH_KINDS

if TYPE_CHECKING:  # for the annotations only: the options module stays cheap to import
    from multiprocessing.synchronize import Event

    from processes.network.server.config import GatewayConfig
    from processes.runtime.handoff import Baton, TurnQueue

# A served match waits this long for its remote players to take their seats, then starts.
PLAYERS_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class RunOptions:
    """One worker's options (pickled to it once, at its start).

    Attributes:
        ticks: ticks the run reaches. mode: "lockstep" or "realtime".
        trace: keep every tick's physics snapshot in the "trace" array.
        crash_at_tick: fault injection for tests and `pingpong stress`: this worker ends at that
            tick (None: never), as crash_kind says: "kill" (SIGKILL) or "raise" (an exception).
            The supervisor sets it for one incarnation of one worker.
        seed: the match's seed. frame_every: keep a snapshot every this many ticks (replays), 0: none.
        players_timeout: s, a served match waits this long for its remote players, then starts.
        gateway: the gateway's configuration, for a scene with the effect "remote".
        ai_queue, net_baton: the AI's turns (processes.runtime.handoff.TurnQueue) and the net's
            turns' baton (None: no such worker). lock_path: the run's lock table (a run with a gateway).
        start_event: set by the gateway while every remote seat is held (a run with a gateway).
        handoff_s: s, the physics waits this long for the AI's or the net's answer to a turn,
            then gives the turn again (a restarted worker takes it) and waits again.
        slow_turn_s: fault injection for tests: this worker answers each turn (the AI, the net)
            or steps each tick of a match (the physics) this much later, as one descheduled on a
            busy machine does (0: never).
        on_bot_error: "point" or "stop" (engine.match.Match). bot_budget_s: CPU s a bot's
            decision may take (engine.players).
        timeline_dir: a directory into which each worker writes its timeline at its end
            (processes.runtime.timeline: when it worked, waited and for whom), None: none kept.
    """

    ticks: int
    mode: str = "lockstep"
    trace: bool = False
    crash_at_tick: int | None = None
    crash_kind: str = "kill"
    seed: int = 0
    frame_every: int = 0
    players_timeout: float = PLAYERS_TIMEOUT_S
    gateway: GatewayConfig | None = None
    ai_queue: TurnQueue | None = None
    net_baton: Baton | None = None
    lock_path: str | None = None
    start_event: Event | None = None
    handoff_s: float = 1.0
    slow_turn_s: float = 0.0
    on_bot_error: str = "point"
    bot_budget_s: float | None = DEFAULT_BUDGET_S
    timeline_dir: str | None = None

    def __post_init__(self):
        if self.mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {self.mode!r}")
        if self.crash_kind not in CRASH_KINDS:
            raise ValueError(f"crash_kind must be one of {', '.join(CRASH_KINDS)}, got {self.crash_kind!r}")
