"""The referee: ITTF rules (Handbook, chapter 2) as a state machine driven by contact events.

Players are 0 (A) and 1 (B). A player's court is the half of the table at its end: x < 0 for A,
x > 0 for B. Rule 2.14 has the players change ends after each game and at 5 points in the
last possible game; that rule exists to even out a real hall's light, floor and draughts. The
simulated hall is symmetric, so the referee records each change of ends (`ends_changed`) but
the players stay where they are (walking the bats around the net would only cost time).

Feed it every contact event of the ball (engine.physics.dtypes.CONTACT_DTYPE) in order, and call
`ball_out_of_play` when the ball leaves the playing area or stops without an event. It decides
each rally with a stated reason, keeps the score, and names the next server.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

from engine.physics import equipment
from engine.physics.geometry import Body

HALF_LENGTH = equipment.TABLE_LENGTH / 2
HALF_WIDTH = equipment.TABLE_WIDTH / 2


class Phase(enum.IntEnum):
    WAITING_SERVE = 0  # ball tossed, the server has not struck it yet
    SERVED = 1  # struck by the server, must bounce on the server's court first
    SERVE_BOUNCED = 2  # bounced on the server's court, must bounce next on the receiver's
    STRUCK = 3  # a return is in the air: must bounce on the opponent's court
    BOUNCED = 4  # bounced once on the court of the player who must now strike it
    OVER = 5  # the rally is decided


class Reason(enum.Enum):
    """Why a rally ended (recorded with every point)."""

    SERVE_MISSED_OWN_COURT = "serve_missed_own_court"  # 2.6.3: first bounce not on the server's court
    SERVE_DOUBLE_BOUNCE = "serve_double_bounce"  # bounced twice on the server's court
    SERVE_WHIFF = "serve_whiff"  # the tossed ball fell without being struck
    NET = "net"  # struck into the net: it fell back on the striker's side or never crossed
    OUT_LONG = "out_long"  # passed the opponent's end line without touching the court
    OUT_SIDE = "out_side"  # passed a side line without touching the court
    OWN_COURT = "own_court"  # a return struck down onto the striker's own court, the net untouched
    DOUBLE_BOUNCE = "double_bounce"  # 2.10.1.3: bounced twice before being returned
    MISSED = "missed"  # bounced legally and was never returned
    DOUBLE_HIT = "double_hit"  # 2.10.1.6: struck twice in succession
    OBSTRUCTION = "obstruction"  # 2.10.1.8: touched above the playing surface before it bounced
    LET = "let"  # 2.9.1.1: a service touching the net assembly, otherwise good: replayed
    BOT_ERROR = "bot_error"  # the player's bot failed a decision (engine.play.bot.FAULTS), the match plays on


REASONS = tuple(Reason)  # stable codes for logs and replay files: REASONS.index(reason)


def next_striker(phase: int, server: int, striker: int) -> int:
    """The player who must strike the ball next, -1 when nobody must (the rally is decided)."""
    if phase == Phase.OVER:
        return -1
    if phase == Phase.WAITING_SERVE:
        return server
    return 1 - striker


@dataclass
class PointRecord:
    game: int
    server: int
    winner: int  # -1 for a let
    reason: Reason
    shots: int  # strikes in the rally, the service included
    score_after: tuple[int, int]


@dataclass
class Referee:
    """Score keeper and rally judge for a match of `best_of` games to 11, won by 2."""

    best_of: int = 5
    first_server: int = 0
    points: list[PointRecord] = field(default_factory=list)
    games: list[tuple[int, int]] = field(default_factory=list)  # finished games' scores (A, B)

    def __post_init__(self):
        if self.best_of < 1 or self.best_of % 2 == 0:
            raise ValueError(f"best_of must be an odd number >= 1, got {self.best_of}")
        self.score = [0, 0]
        self.games_won = [0, 0]
        self._game_first_server = self.first_server
        self._deciding_ends_swapped = False
        self.winner: int | None = None
        self._new_rally()

    # --- where things are -----------------------------------------------------------------
    @property
    def game(self) -> int:
        """Index of the game being played, 0-based."""
        return len(self.games)

    def end_sign(self, player: int) -> int:
        """-1 if `player`'s court is at x < 0, +1 otherwise."""
        return -1 if player == 0 else 1

    @property
    def ends_changed(self) -> int:
        """How many times rule 2.14 has had the players change ends so far."""
        return self.game + (1 if self._deciding_ends_swapped else 0)

    def court_of(self, x: float) -> int:
        """The player whose court contains x."""
        return 0 if (x < 0) == (self.end_sign(0) < 0) else 1

    @property
    def server(self) -> int:
        """Who serves the current rally (rule 2.13: two each, one each from 10-10)."""
        played = sum(self.score)
        turns = played // 2 if played < 20 else 10 + (played - 20)
        return self._game_first_server if turns % 2 == 0 else 1 - self._game_first_server

    @property
    def receiver(self) -> int:
        return 1 - self.server

    @property
    def match_over(self) -> bool:
        return self.winner is not None

    # --- the rally ------------------------------------------------------------------------
    def _new_rally(self) -> None:
        self.phase = Phase.WAITING_SERVE
        self.striker = self.server  # who struck last (or must serve)
        self.shots = 0
        self.touched_net = False
        self.last_point: PointRecord | None = None

    def on_contact(self, body: int, pos) -> PointRecord | None:
        """Judge one contact event; returns the point record if it decided the rally."""
        if self.phase == Phase.OVER or self.match_over:
            return None
        x, y = float(pos[0]), float(pos[1])
        if body in (Body.NET, Body.POST):
            self.touched_net = True
            return None
        if body in (Body.BAT_A, Body.BAT_B):
            return self._strike(int(body) - Body.BAT_A, x, y)
        if body == Body.TABLE:
            return self._bounce(x, y)
        if body == Body.FLOOR:
            return self.ball_out_of_play(x, y)
        return None

    def _strike(self, player: int, x: float, y: float) -> PointRecord | None:
        other = 1 - player
        if self.phase == Phase.WAITING_SERVE:
            if player != self.server:
                return self._award(self.server, Reason.OBSTRUCTION)
            self.phase, self.striker, self.shots, self.touched_net = Phase.SERVED, player, 1, False
            return None
        if player == self.striker:
            return self._award(other, Reason.DOUBLE_HIT)
        if self.phase == Phase.BOUNCED:  # the legal return
            self.phase, self.striker, self.touched_net = Phase.STRUCK, player, False
            self.shots += 1
            return None
        # Struck before it bounced on the striker's court (volley).
        over_table = abs(x) <= HALF_LENGTH and abs(y) <= HALF_WIDTH
        if over_table:
            return self._award(other, Reason.OBSTRUCTION)
        # Beyond the table it could no longer land in: the ball was out.
        return self._award(player, self._out_reason(x, y))

    def _bounce(self, x: float, y: float) -> PointRecord | None:
        court = self.court_of(x)
        striker, other = self.striker, 1 - self.striker
        if self.phase == Phase.WAITING_SERVE:
            return self._award(1 - self.server, Reason.SERVE_WHIFF)
        if self.phase == Phase.SERVED:
            if court != striker:
                return self._award(other, Reason.SERVE_MISSED_OWN_COURT)
            self.phase, self.touched_net = Phase.SERVE_BOUNCED, False
            return None
        if self.phase == Phase.SERVE_BOUNCED:
            if court == striker:
                return self._award(other, Reason.NET if self.touched_net else Reason.SERVE_DOUBLE_BOUNCE)
            if self.touched_net:
                return self._let()
            self.phase = Phase.BOUNCED
            return None
        if self.phase == Phase.STRUCK:
            if court == striker:  # a player would say "into the net" when it fell back off the net
                return self._award(other, Reason.NET if self.touched_net else Reason.OWN_COURT)
            self.phase = Phase.BOUNCED
            return None
        # Phase.BOUNCED: a second bounce before the return, wherever it lands.
        return self._award(striker, Reason.DOUBLE_BOUNCE)

    def ball_out_of_play(self, x: float, y: float) -> PointRecord | None:
        """The ball hit the floor, left the playing area or came to rest: decide the rally."""
        if self.phase == Phase.OVER or self.match_over:
            return None
        striker, other = self.striker, 1 - self.striker
        if self.phase == Phase.WAITING_SERVE:
            return self._award(1 - self.server, Reason.SERVE_WHIFF)
        if self.phase == Phase.BOUNCED:
            return self._award(striker, Reason.MISSED)
        if self.phase == Phase.SERVED:
            return self._award(other, Reason.SERVE_MISSED_OWN_COURT)
        # SERVE_BOUNCED or STRUCK: it never reached the opponent's court.
        return self._award(other, self._out_reason(x, y))

    def award_fault(self, player: int) -> PointRecord | None:
        """The player's bot failed a decision: the rally in play goes to the other player (None
        when no rally is in play: decided already, or the match is over)."""
        if self.phase == Phase.OVER or self.match_over:
            return None
        return self._award(1 - player, Reason.BOT_ERROR)

    def _out_reason(self, x: float, y: float) -> Reason:
        """Why a struck ball that never touched the opponent's court is out, from where it ended."""
        if self.court_of(x) == self.striker:
            return Reason.NET  # it never crossed: stopped by the net or fell short of it
        return Reason.OUT_LONG if abs(x) > HALF_LENGTH else Reason.OUT_SIDE

    # --- scoring --------------------------------------------------------------------------
    def _let(self) -> PointRecord:
        record = PointRecord(self.game, self.server, -1, Reason.LET, self.shots, tuple(self.score))
        self.points.append(record)
        self.phase = Phase.OVER
        self.last_point = record
        return record

    def _award(self, winner: int, reason: Reason) -> PointRecord:
        server = self.server
        self.score[winner] += 1
        record = PointRecord(self.game, server, winner, reason, self.shots, tuple(self.score))
        self.points.append(record)
        self.phase = Phase.OVER
        self.last_point = record
        a, b = self.score
        if max(a, b) >= 11 and abs(a - b) >= 2:
            self._end_game(0 if a > b else 1)
        elif self.game == self.best_of - 1 and max(a, b) == 5 and min(a, b) < 5 and not self._deciding_ends_swapped:
            self._deciding_ends_swapped = True  # rule 2.14.2: change ends at 5 in the last game
        return record

    def _end_game(self, winner: int) -> None:
        self.games.append((self.score[0], self.score[1]))
        self.games_won[winner] += 1
        self.score = [0, 0]
        self._deciding_ends_swapped = False
        # Rule 2.13.3: whoever served first in a game receives first in the next.
        self._game_first_server = 1 - self._game_first_server
        if self.games_won[winner] > self.best_of // 2:
            self.winner = winner

    # --- persistence (restarts, replays) ------------------------------------------------------
    def save(self, record) -> None:
        """Write the referee's state into a RALLY_DTYPE record (the match fills rally and rally_started)."""
        record["shots"] = self.shots
        record["phase"] = int(self.phase)
        record["server"] = self.server
        record["striker"] = self.striker
        record["touched_net"] = int(self.touched_net)
        record["score"] = self.score
        record["games_won"] = self.games_won
        record["game_first_server"] = self._game_first_server
        record["deciding_ends_swapped"] = int(self._deciding_ends_swapped)
        record["winner"] = -1 if self.winner is None else self.winner
        record["points_total"] = len(self.points)

    @classmethod
    def restore(cls, record, best_of: int, first_server: int, points: list[PointRecord]) -> "Referee":
        """Rebuild a referee from a saved record and the point log (finished games from the log)."""
        ref = cls(best_of=best_of, first_server=first_server)
        ref.points = list(points)
        games = {}
        for p in points:
            if p.winner >= 0:
                games[p.game] = p.score_after
        finished = int(record["games_won"][0] + record["games_won"][1])
        ref.games = [tuple(int(v) for v in games[g]) for g in range(finished)]
        ref.score = [int(v) for v in record["score"]]
        ref.games_won = [int(v) for v in record["games_won"]]
        ref._game_first_server = int(record["game_first_server"])
        ref._deciding_ends_swapped = bool(record["deciding_ends_swapped"])
        ref.winner = None if int(record["winner"]) < 0 else int(record["winner"])
        ref.phase = Phase(int(record["phase"]))
        ref.striker = int(record["striker"])
        ref.shots = int(record["shots"])
        ref.touched_net = bool(record["touched_net"])
        ref.last_point = points[-1] if points else None
        return ref

    def next_rally(self) -> None:
        """Start the next rally after a decided one (the caller re-tosses the ball)."""
        if self.phase != Phase.OVER:
            raise RuntimeError("next_rally() called while a rally is still being played")
        self._new_rally()
