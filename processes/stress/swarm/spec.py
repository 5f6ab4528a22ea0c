"""The watch task's spec: what a swarm process of spectators and players is asked to do."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

TIMED_EVERY = 20  # one spectator in this many is timed: read as soon as its socket signals
BULK_PERIOD_S = 0.05  # the other feeds are read this often, a few snapshots a visit
VALIDATE_EVERY = 500  # one snapshot in this many (of the process) is decoded in full


@dataclass(frozen=True)
class WatchSpec:
    """One watch swarm, as it crosses to its process (JSON, `python -m processes.stress.swarm`).

    address: the gateway's endpoint; spectators, players: how many of each; name: the clients'
    name prefix; record: an .npz path for the timed snapshots' ticks and receipt times (None: no
    record); duration: s from the start to the end of the receive loop; join_timeout: s to wait
    for every welcome before the measured window starts anyway; silence_s: with rejoin, a client
    silent this long says hello again; input_hz: a player's zero-force inputs a second; rejoin:
    hello again after silence or goodbye unknown_session (a restarted gateway); until_goodbye:
    stop once every client was told goodbye; leave_at_end: say goodbye at the end; pin_cpu: the
    CPU the process is pinned to (None: any); nice: the priority lowered by this once the clients
    are in (0: not); validate_every, timed_every, bulk_period_s: see swarm.watch.
    """

    address: str
    spectators: int = 0
    players: int = 0
    name: str = "w"
    record: str | None = None
    duration: float = 10.0
    join_timeout: float = 30.0
    silence_s: float = 1.0
    input_hz: float = 50.0
    rejoin: bool = False
    until_goodbye: bool = False
    leave_at_end: bool = True
    pin_cpu: int | None = None
    nice: int = 0
    validate_every: int = VALIDATE_EVERY
    timed_every: int = TIMED_EVERY
    bulk_period_s: float = BULK_PERIOD_S

    def __post_init__(self):
        if self.spectators < 0 or self.players < 0:
            raise ValueError(f"watch spec: spectators {self.spectators} and players {self.players} must be >= 0")
        for name in ("validate_every", "timed_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"watch spec: {name} {getattr(self, name)} must be >= 1")
        for name in ("bulk_period_s", "input_hz"):
            if not getattr(self, name) > 0:
                raise ValueError(f"watch spec: {name} {getattr(self, name)} must be > 0")

    @classmethod
    def from_json(cls, spec: dict) -> WatchSpec:
        """The spec a launched process was given ({"task": "watch", ...}); unknown keys are refused."""
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(spec) - fields - {"task"})
        if unknown:
            raise ValueError(f"watch spec: unknown keys {unknown}; the keys are {sorted(fields)}")
        return cls(**{k: v for k, v in spec.items() if k != "task"})

    def to_json(self) -> dict:
        """The spec as `launch` hands it to the swarm process."""
        return {"task": "watch", **dataclasses.asdict(self)}
