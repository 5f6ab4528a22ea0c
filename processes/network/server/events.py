"""MatchEvents: which point, game and match events the gateway announces, from the run's point log."""
from __future__ import annotations

from collections import Counter

from processes.network import wire
from processes.network.wire import Kind


class MatchEvents:
    """The events of the points the physics logged since the last look: a point event for each
    point, a game event when the games won changed, one match event when there is a winner.

    A gateway (re)started mid-match announces only the points after its first look. Point i of
    the log decided rally i + 1, the number its snapshots carried (wire.Snapshot). counts:
    events_unencodable (a row the wire cannot carry: that event is skipped).
    """

    def __init__(self):
        self.points_seen: int | None = None
        self.games_seen = (0, 0)
        self.match_sent = False
        self.counts: Counter[str] = Counter()

    def new(self, record, points, tick: int) -> list[bytes]:
        """The event messages (header tick `tick`) of `record`'s points not announced yet.

        record: one physics_snapshot_dtype record. points: the run's POINT_DTYPE log."""
        rally = record["rally"]
        total = int(rally["points_total"])
        if self.points_seen is None:
            self.points_seen = total
            self.games_seen = tuple(int(g) for g in rally["games_won"])
        games = tuple(int(g) for g in rally["games_won"])
        events = [(wire.EventKind.POINT, points[i], i + 1) for i in range(self.points_seen, min(total, len(points)))]
        if total > self.points_seen and games != self.games_seen and total <= len(points):
            events.append((wire.EventKind.GAME, points[total - 1], total))
        self.points_seen, self.games_seen = total, games
        if int(rally["winner"]) >= 0 and not self.match_sent and 1 <= total <= len(points):
            self.match_sent = True
            events.append((wire.EventKind.MATCH, points[total - 1], total))
        return [data for data in (self._encode(kind, row, games, number, tick) for kind, row, number in events)
                if data is not None]

    def _encode(self, kind, row, games, rally: int, tick: int) -> bytes | None:
        try:
            return wire.encode(Kind.EVENT, tick=tick, event=kind, winner=int(row["winner"]), reason=int(row["reason"]),
                               game=int(row["game"]), score=row["score_after"], games_won=games,
                               shots=int(row["shots"]), rally=rally)
        except wire.WireError:
            self.counts["events_unencodable"] += 1
            return None
