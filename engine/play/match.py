"""A whole match in one process: physics, referee, the AIs and the server's toss.

This is the reference the multi-process match must reproduce bit for bit in lockstep. A player
is a brain and an arm. At each AI control tick B (every P ticks) the players decide from the
state at B (their plans: an arm target to track, a raw force, or the idle arm's brake), and the
plans decided at B - D take effect (D = CompiledScene.decision_delay: match.decision_latency
in whole control periods); the arm law (engine.play.arm.control_bats) then turns the plans in
effect and the bats' state at B into the forces and torques held until B + P; the physics steps
to B + P; the referee judges each tick's contact events; a decided rally is followed by the next server's toss.

The decision latency is what lets the physics and the AI run at the same time in separate
processes: the AI thinks about the state at B while the physics steps B .. B + D, and nothing
waits unless the AI is slower than D ticks of physics. It is a player's too: between seeing and
a new movement lies a human's visuomotor delay of 100-200 ms (the profiles' reaction times,
engine.play.ai.skill, start there), while the arm's own feedback (the PD law on the bat's current
state, a reflex and the muscles' stiffness) acts at once.
"""
from __future__ import annotations

import hashlib
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from engine.physics import equipment
from engine.play.bot import ON_BOT_ERROR, BotError, bot_source
from engine.physics.dtypes import CONTACT_DTYPE, POINT_DTYPE, physics_snapshot_dtype
from engine.physics.scene import Scene, SceneError, is_bot_spec, scene_digest, with_skills
from engine.physics.compiled import CompiledScene, compile_scene
from engine.physics.world import advance, copy_record, new_events, step
from engine.play.arm import ARM_BRAKE, BAT_FLOATS, CTL_KIND, CTL_MASS, CTL_SIZE, control_bats
from engine.play.players import DEFAULT_BUDGET_S, Players, make_players
from engine.play.rules import REASONS, Phase, PointRecord, Referee

OUT_OF_PLAY_DISTANCE = 4.0  # m from the table's centre: the ball is gone
_GONE_RADIUS_2 = OUT_OF_PLAY_DISTANCE**2
_GONE_Z = -equipment.TABLE_HEIGHT  # m: the floor


@dataclass
class MatchResult:
    scene: Scene
    seed: int
    referee: Referee
    ticks: int
    sim_seconds: float
    wall_seconds: float
    compile_seconds: float
    ai_seconds: float
    ai_stats: dict = field(default_factory=dict)
    bot_errors: list = field(default_factory=list)  # Match.bot_errors
    stopped: str | None = None  # the bot error that stopped the match

    def summary(self) -> dict:
        ref = self.referee
        decided = [p for p in ref.points if p.winner >= 0]
        reasons: dict[str, int] = {}
        for p in decided:
            reasons[p.reason.value] = reasons.get(p.reason.value, 0) + 1
        shots = [p.shots for p in decided]
        served = [p for p in decided if p.shots >= 1]
        returned = [p for p in served if p.shots >= 2]
        return {
            "scene": self.scene.name,
            "seed": self.seed,
            "winner": None if ref.winner is None else "ab"[ref.winner],
            "games": [list(g) for g in ref.games],
            "score_in_game": list(ref.score),
            "points": len(decided),
            "lets": sum(1 for p in ref.points if p.winner < 0),
            "points_won": [sum(1 for p in decided if p.winner == k) for k in (0, 1)],
            "mean_rally_shots": float(np.mean(shots)) if shots else 0.0,
            "max_rally_shots": int(max(shots)) if shots else 0,
            "serves_returned": len(returned) / len(served) if served else 0.0,
            "point_reasons": dict(sorted(reasons.items(), key=lambda kv: -kv[1])),
            "ticks": self.ticks,
            "sim_seconds": self.sim_seconds,
            "wall_seconds": self.wall_seconds,
            "compile_seconds": self.compile_seconds,
            "ai_seconds": self.ai_seconds,
            "realtime_factor": self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else None,
            "ai": self.ai_stats,
            "bot_errors": self.bot_errors,
            "stopped": self.stopped,
        }


def make_ais(scene: Scene | CompiledScene, seed: int, eager: bool = True, budget_s: float | None = DEFAULT_BUDGET_S,
             interrupt: bool | None = None) -> Players:
    """The player of every bat that has one (an AI profile or a bot) of a scene (compiled here if it
    is not yet: engine.physics.compiled), seeded from the match seed
    and its player (engine.play.players.make_players). interrupt: stop a bot's hung decision with
    SIGALRM; None: wherever this is a process's main thread.

    eager=False: each AI profile thinks a stroke out only in the steps its think_step is given
    (and what is left when it is due), as the AI worker does between its turns; the same strokes.
    """
    run = compile_scene(scene)
    return make_players(run.scene, run.model, seed, run.control_period, run.decision_delay, eager=eager,
                        budget_s=budget_s, interrupt=interrupt)


def ai_decide(players: Players, tick: int, now: float, ball_flat: np.ndarray, bats: np.ndarray, rally,
              before=None) -> list:
    """Every player's decision from one state, into its plan (players.ctl): the one function both
    the in-process match and the AI worker call, so lockstep runs decide bit for bit the same.

    ball_flat: (9,) the ball; bats: the (n_bats,) BAT_DTYPE array; rally: the state's
    RALLY_DTYPE record; before: Players.decide's. Returns the decisions' faults [(player, fault,
    detail)] (engine.play.bot.FAULTS names).
    """
    return players.decide(tick, now, ball_flat, bats, rally, before)


def idle_arms(model, ai_bats: list[int]) -> np.ndarray:
    """(len(ai_bats), CTL_SIZE): the plans in effect before any decision took effect: each arm
    brakes its bat (engine.play.arm.ARM_BRAKE)."""
    arms = np.zeros((len(ai_bats), CTL_SIZE))
    arms[:, CTL_KIND] = ARM_BRAKE
    arms[:, CTL_MASS] = model.bat_mass[ai_bats]
    return arms


def point_row(point: PointRecord, tick: int) -> np.ndarray:
    """A point as a POINT_DTYPE record."""
    row = np.zeros((), POINT_DTYPE)
    row["tick"], row["game"], row["server"], row["winner"] = tick, point.game, point.server, point.winner
    row["reason"], row["shots"], row["score_after"] = REASONS.index(point.reason), point.shots, point.score_after
    return row


def point_from_row(row) -> PointRecord:
    return PointRecord(int(row["game"]), int(row["server"]), int(row["winner"]), REASONS[int(row["reason"])],
                       int(row["shots"]), tuple(int(v) for v in row["score_after"]))


# A fault of a player's decision: (player index, tick of the decision, engine.play.players fault name, detail).
Fault = tuple[int, int, str, str]


class PlayerDriver(Protocol):
    """What drives a Match's AI players (its ai_driver): LocalAI here, or a stand-in that does the
    same in another process and gives the same bits (the physics worker's, which asks the AI
    worker). Any object with these members fits.

    At each AI control tick B the match calls collect(), then request(); the plans decided at
    B - match.delay take effect at B.
    """

    def collect(self, match: Match, tick: int) -> list[Fault]:
        """Write the plans decided at tick - match.delay, if any decision was taken then, into
        match.arm; returns that decision's faults."""

    def request(self, match: Match, now: float) -> None:
        """Start the players' decision from the match's state now (s of simulated time)."""

    def resume(self, match: Match, tick: int) -> None:
        """After the match was restored at `tick`: the plans in effect into match.arm, and the
        decisions in flight taken up again."""


class LocalAI:
    """The players in this process (the reference PlayerDriver): each control tick they decide at
    once, and their plans and faults wait match.delay ticks to reach the match, as the AI
    worker's do."""

    def __init__(self, ais: Players):
        self.ais = ais
        self.pending: deque = deque()  # (tick it takes effect, plans, faults) of each decision, oldest first

    def collect(self, match: Match, tick: int) -> list[Fault]:
        if not self.pending or self.pending[0][0] != tick:
            return []
        _, plans, faults = self.pending.popleft()
        match.arm[:] = plans
        return faults

    def resume(self, match: Match, tick: int) -> None:
        """Nothing to take up: this driver lives as long as its match."""

    def request(self, match: Match, now: float) -> None:
        tick = match.current_tick
        faults = ai_decide(self.ais, tick, now, match.state.ball_flat, match.state.bats, match.rally_record)
        if self.ais.decided:  # otherwise the plans stay as they are
            self.pending.append((tick + match.delay, self.ais.ctl.copy(),
                                 [(player, tick, fault, detail) for player, fault, detail in faults]))


class Match:
    """A match between the scene's two bats, judged by the referee, AIs where the scene has them.

    At each AI control tick the match calls ai_driver.collect(match, tick), which writes into
    match.arm the plans decided `delay` ticks before (if any) and returns their faults, turns the
    plans in effect into the bats' forces (engine.play.arm.control_bats on the bats' state now), then
    calls ai_driver.request(match, now), which starts the decision from the state now (the
    contract: PlayerDriver). By default the players run here (LocalAI, the reference); the
    physics worker passes a driver that asks the AI worker.

    A player's decision that goes wrong (engine.play.players: it raised, was malformed, non-finite,
    oversized or overran its budget_s of CPU) is recorded in bot_errors when it is collected;
    on_bot_error "point" gives the rally to the other player (reason bot_error), "stop" ends
    the match there (stopped holds the BotError).

    `scene` is a Scene or the run's CompiledScene (engine.physics.compiled): a worker passes the
    one the supervisor compiled; a Scene is compiled here.
    """

    def __init__(self, scene: Scene | CompiledScene, seed: int = 0, ai_driver: PlayerDriver | None = None,
                 on_bot_error: str = "point", budget_s: float | None = DEFAULT_BUDGET_S):
        run = compile_scene(scene)
        scene = run.scene
        if scene.match is None:
            raise ValueError(f"{scene.source}: scene {scene.name!r} has no referee; a match needs the effect 'referee'")
        self.compiled = run
        self.scene = scene
        self.model = run.model
        if on_bot_error not in ON_BOT_ERROR:
            raise ValueError(f"on_bot_error: must be one of {', '.join(ON_BOT_ERROR)}, got {on_bot_error!r}")
        self.on_bot_error = on_bot_error
        self.has_ai = any(bat.skill is not None for bat in scene.bats)
        self.ais = make_ais(run, seed, budget_s=budget_s) if ai_driver is None else {}
        self.ai_driver: PlayerDriver = ai_driver or LocalAI(self.ais)
        self.ai_bats = [i for i, bat in enumerate(scene.bats) if bat.skill is not None]
        self._ai_players = np.array(self.ai_bats, np.int64)
        self.ai_every = run.control_period
        self.delay = run.decision_delay
        self._max_rally_s = scene.match.max_rally_s
        self._begin(seed)

    def renew(self, seed: int) -> None:
        """The match of this seed from its first toss, as Match(self.compiled, seed) begins it:
        its players renewed (engine.play.players.Players.renew: an AI profile keeps its arrays),
        a new state. For a match whose players are in this process (LocalAI): an environment's
        next episode (engine.learning.env)."""
        if not isinstance(self.ai_driver, LocalAI):
            raise ValueError("Match.renew: the players are not in this process (a driver other than LocalAI); "
                             "make a new Match")
        self.ais.renew(seed)
        self.ai_driver = LocalAI(self.ais)
        self._begin(seed)

    def _begin(self, seed: int) -> None:
        """The state, the referee and the bookkeeping of a match at its first toss."""
        run, scene = self.compiled, self.scene
        self.seed = seed
        self.state = run.initial_state()
        self.events = new_events()
        spec = scene.match
        self.referee = Referee(best_of=spec.best_of, first_server="ab".index(spec.first_server))
        self.bot_errors: list[dict] = []
        self.stopped: BotError | None = None
        self.inputs = np.zeros((len(scene.bats), 6))  # held by the bats until the next control tick
        self.arm = idle_arms(self.model, self.ai_bats)  # the AI bats' plans in effect (engine.play.arm's ctl rows)
        self._bat_floats = self.state.bats.view(np.float64).reshape(len(scene.bats), BAT_FLOATS)
        # Per call of tick(), which runs once a control period or more often: its Python is part
        # of every chunk the physics worker steps, so its constants and views are made here once.
        # The world record's words, read through typed memoryviews (cheaper than numpy fields):
        # tick (int64 word 0), time (float64 word 1), ball_support (int32 word 4).
        world_bytes = memoryview(self.state.world.view(np.uint8)).cast("B")
        self._world_q, self._world_d, self._world_i = world_bytes.cast("q"), world_bytes.cast("d"), world_bytes.cast("i")
        self.rally_record = self.state.record[0]["rally"]  # a view: the players read the referee's state here
        self.rally = 0
        self.rally_started = 0.0
        self.n_events = 0
        self.ticks_done = 0
        self.ai_seconds = 0.0
        self.toss()

    def toss(self) -> None:
        """The server holds the ball 10 cm behind its end line and tosses it straight up."""
        ref = self.referee
        sign = ref.end_sign(ref.server)
        ball = self.state.ball[0]
        ball["pos"] = (sign * (equipment.TABLE_LENGTH / 2 + 0.1), 0.0, 0.12)
        ball["vel"] = (0.0, 0.0, self.scene.match.toss_speed)
        ball["spin"] = (0.0, 0.0, 0.0)
        self.state.world[0]["ball_support"] = 0
        self.rally_started = float(self.state.world[0]["time"])
        self._sync_rally()

    def rally_key(self) -> tuple[int, int]:
        """Changes whenever the ball changes hands."""
        return (self.rally, self.referee.shots)

    def _sync_rally(self) -> None:
        """Write the referee and rally bookkeeping into the state record (only when they change)."""
        rally = self.state.record[0]["rally"]
        self.referee.save(rally)
        rally["rally"] = self.rally
        rally["rally_started"] = self.rally_started

    def save(self, record: np.ndarray, index: int = 0) -> None:
        """The whole match state into record[index] (a physics_snapshot_dtype array)."""
        copy_record(self.state.record, record, index)

    def restore(self, record, points: list[PointRecord]) -> None:
        """Resume from a saved record and the point log (a restarted physics worker).

        The plans in effect and the decisions in flight are not in the record: they belong to the
        driver, whose resume(match, tick) takes them up again (the AI worker keeps its answers).
        """
        self._restore_record(record, points)
        self.ai_driver.resume(self, int(self.state.world[0]["tick"]))

    def checkpoint(self) -> tuple:
        """What rollback() takes the match back to: the state now (one record's copy), the count
        of points decided and the plans in effect. The driver's decisions in flight are its own."""
        return self.state.record.view(np.uint8).copy(), len(self.referee.points), self.arm.copy()

    def rollback(self, checkpoint: tuple) -> None:
        """Back to a checkpoint(), bit for bit: a speculating physics worker whose guess went
        wrong (processes.workers.speculation) steps again from there."""
        record, points, arm = checkpoint
        self.state.record.view(np.uint8)[:] = record  # every byte as it was, the rally's too
        self._restore_record(self.state.record[0], self.referee.points[:points])
        self.arm[:] = arm

    def _restore_record(self, record, points: list[PointRecord]) -> None:
        """The state, the held forces and the referee from a record and the point log."""
        self.state.ball[0] = record["ball"]
        self.state.bats[:] = record["bats"]
        self.state.world[0] = record["world"]
        # The AI's forces are held between its control ticks: they are state, kept in the bats.
        self.inputs[:, 0:3] = self.state.bats["force"]
        self.inputs[:, 3:6] = self.state.bats["torque"]
        rally = record["rally"]
        spec = self.scene.match
        self.referee = Referee.restore(rally, spec.best_of, "ab".index(spec.first_server), points)
        self.rally = int(rally["rally"])
        self.rally_started = float(rally["rally_started"])
        self._sync_rally()

    def tick(self, max_ticks: int = 1) -> PointRecord | None:
        """Advance up to max_ticks ticks, stopping where the match must act; returns a point
        record when a rally was decided.

        Each call starts, at the AI's control ticks, with the plans that take effect, the forces
        they give and the AIs' next decision; then the engine advances until the next control tick, a contact event (judged here), the ball
        leaving the area or coming to rest, or the rally's time limit, all checked tick by tick
        inside the kernel, so any max_ticks gives the same match.
        """
        tick = self._world_q[0]
        inputs = None  # between the AI's control ticks the bats keep their inputs (held in their records)
        n_max = max_ticks
        if self.has_ai:
            every = self.ai_every
            if tick % every == 0:
                started = time.perf_counter()
                faults = self.ai_driver.collect(self, tick)
                if faults:
                    self._faults(faults)
                    if self.stopped is not None:
                        self.ticks_done = self.n_events = 0
                        return None
                now = self._world_d[1]
                control_bats(now, self._bat_floats, self.arm, self._ai_players, self.inputs)
                self.ai_driver.request(self, now)
                self.ai_seconds += time.perf_counter() - started
                inputs = self.inputs
            n_max = min(n_max, every - tick % every)
        deadline = self.rally_started + self._max_rally_s
        ticks, n, _ = advance(self.model, self.state, n_max, inputs, self.events, gone_radius=OUT_OF_PLAY_DISTANCE,
                              gone_z=_GONE_Z, deadline=deadline)
        self.ticks_done = ticks
        self.n_events = n
        point = None
        referee = self.referee
        for k in range(n):
            point = referee.on_contact(int(self.events[k]["body"]), self.events[k]["pos"]) or point
        if point is None and referee.phase != Phase.OVER:
            x, y, z = self.state.ball_flat[0:3].tolist()  # Python floats: the same doubles, cheaper arithmetic
            gone = x * x + y * y > _GONE_RADIUS_2 or z < _GONE_Z
            if gone or self._world_i[4] != 0 or self._world_d[1] > deadline:  # ball_support: resting
                point = referee.ball_out_of_play(x, y)
        if point is not None and not self.referee.match_over:
            self.referee.next_rally()
            self.rally += 1
            self.toss()
        elif n or point is not None:
            self._sync_rally()
        return point

    @property
    def current_tick(self) -> int:
        """The tick the state is at (ticks done)."""
        return int(self._world_q[0])

    @property
    def over(self) -> bool:
        """The match is won, or stopped by a bot's fault."""
        return self.referee.match_over or self.stopped is not None

    def _faults(self, faults: list[Fault]) -> None:
        """Record the faults of a decision; the point to the other player or the match stopped."""
        for player, tick, fault, detail in faults:
            bat = self.scene.bats[player]
            error = BotError(bat.skill, player, tick, fault, detail)
            self.bot_errors.append({"player": "ab"[player], "bot": bat.skill, "tick": tick, "fault": fault,
                                    "detail": detail})
            if self.on_bot_error == "stop":
                self.stopped = error
                return
            if self.referee.award_fault(player) is None:
                continue
            if self.referee.match_over:
                self._sync_rally()
                return
            self.referee.next_rally()
            self.rally += 1
            self.toss()

    def play(self, max_ticks: int | None = None, on_point: Callable[[Match, PointRecord], None] | None = None,
             on_tick: Callable[[Match, int], None] | None = None, events_out: list | None = None) -> MatchResult:
        """Play until the match is won (or max_ticks).

        on_point(match, record) after each rally; on_tick(match, tick) after each tick; contact
        events are appended to events_out if given.
        """
        limit = self.scene.ticks if max_ticks is None else max_ticks
        compile_start = time.perf_counter()
        step(self.model, self.state, None, self.events, dt=0.0)  # compile or load the kernels
        if self.ais:
            self.ais.warm_up()
        compile_seconds = time.perf_counter() - compile_start
        start = time.perf_counter()
        ticks = 0
        chunk = 1 if on_tick is not None else 1 << 30  # per-tick callbacks see every tick
        decided = len(self.referee.points)
        while ticks < limit and not self.over:
            point = self.tick(min(chunk, limit - ticks))
            if point is None and len(self.referee.points) > decided:  # a bot's fault gave the rally away
                point = self.referee.points[-1]
            decided = len(self.referee.points)
            ticks += self.ticks_done
            if events_out is not None and self.n_events:
                events_out.extend(self.events[: self.n_events].copy())
            if on_tick is not None:
                on_tick(self, int(self.state.world[0]["tick"]))
            if point is not None and on_point is not None:
                on_point(self, point)
        wall = time.perf_counter() - start
        return MatchResult(self.scene, self.seed, self.referee, ticks, ticks * self.model.dt, wall, compile_seconds,
                           self.ai_seconds, self.ais.stats if self.ais else {}, self.bot_errors,
                           None if self.stopped is None else str(self.stopped))


def match_scene(scene: Scene, skill_a: str, skill_b: str, best_of: int | None = None) -> Scene:
    """The scene of one match of a tournament: bat A played by skill_a, bat B by skill_b, best_of
    games (default: the scene's)."""
    if scene.match is None:
        raise SceneError(f"{scene.source}: scene {scene.name!r} has no referee; a match needs the effect 'referee'")
    played = with_skills(scene, skill_a, skill_b)
    if best_of is not None:
        if not (isinstance(best_of, int) and 1 <= best_of <= 9 and best_of % 2 == 1):
            raise SceneError(f"best_of: must be an odd whole number in [1, 9], got {best_of!r}")
        played = replace(played, match=replace(played.match, best_of=best_of))
    return played


def match_hash(scene: Scene, max_ticks: int) -> str:
    """16 hex digits naming one match's conditions: the scene it plays (skills and best_of in it),
    the source of its file bots and its tick bound. With the seed and the code, they decide the match."""
    digest = hashlib.sha256(f"{scene_digest(scene)}/{max_ticks}".encode())
    for bat in scene.bats:
        source = bot_source(bat.skill) if bat.skill is not None and is_bot_spec(bat.skill) else None
        if source is not None:
            digest.update(source.encode())
    return digest.hexdigest()[:16]


def match_record(scene: Scene, seed: int, skill_a: str, skill_b: str, best_of: int | None = None,
                 max_ticks: int | None = None, on_bot_error: str = "point",
                 budget_s: float | None = DEFAULT_BUDGET_S) -> dict:
    """Play one match in this process and describe it in a small JSON-able record
    (MatchRecorder.record)."""
    return MatchRecorder(scene, seed, skill_a, skill_b, best_of, max_ticks, on_bot_error, budget_s).play()


class MatchRecorder:
    """One match played in this process, and its record.

    The record: a, b (the skills at ends A and B), seed, scene (its name), scene_hash
    (match_hash), best_of, winner ("a", "b", or None when max_ticks came first), games (finished games'
    scores), points (won by A, by B), lets, reasons (per end, the reasons of the points it
    lost), mean_rally_shots, ticks, sim_seconds, wall_seconds (the play, not the kernels' load),
    record_hash: sha256 over the match's contact events, point log and final state, so two runs
    of a match compare by one string; bot_errors (Match.bot_errors without their details,
    which may hold times) and stopped (whether a bot's fault stopped the match); with
    `abandoned`, why the match was given up where it stood (a bot that could not be
    interrupted). skill_a and skill_b are AI profiles or bot specs (engine.play.bot.load_bot).
    """

    def __init__(self, scene: Scene, seed: int, skill_a: str, skill_b: str, best_of: int | None = None,
                 max_ticks: int | None = None, on_bot_error: str = "point",
                 budget_s: float | None = DEFAULT_BUDGET_S):
        self.played = match_scene(scene, skill_a, skill_b, best_of)
        self.limit = self.played.ticks if max_ticks is None else max_ticks
        self.skills, self.seed = (skill_a, skill_b), seed
        self.match = Match(self.played, seed=seed, on_bot_error=on_bot_error, budget_s=budget_s)
        self.events: list = []
        self.point_ticks: list[int] = []
        self.started = time.perf_counter()

    def play(self) -> dict:
        """Play the match to its end or its tick bound; its record."""
        def on_point(m, point) -> None:  # every point decided in the call: a bot's fault may add one before
            self.point_ticks.extend([int(m.state.world[0]["tick"])] * (len(m.referee.points) - len(self.point_ticks)))

        self.started = time.perf_counter()
        result = self.match.play(max_ticks=self.limit, events_out=self.events, on_point=on_point)
        return self.record(result.wall_seconds)

    def record(self, wall_seconds: float | None = None, abandoned: str | None = None) -> dict:
        """The record of the match as it stands (abandoned: why it was given up there)."""
        match, played = self.match, self.played
        points = match.referee.points
        final = np.zeros(1, physics_snapshot_dtype(len(played.bats)))
        match.save(final)
        ticks = int(final[0]["world"]["tick"])
        digest = hashlib.sha256()
        digest.update(np.array(self.events, CONTACT_DTYPE).tobytes())
        digest.update(b"".join(point_row(p, tick).tobytes() for p, tick in zip(points, self.point_ticks)))
        digest.update(final.tobytes())
        reasons: dict[str, dict[str, int]] = {"a": {}, "b": {}}
        decided = [p for p in points if p.winner >= 0]
        for p in decided:
            lost = reasons["ba"[p.winner]]
            lost[p.reason.value] = lost.get(p.reason.value, 0) + 1
        referee = match.referee
        record = {
            "a": self.skills[0],
            "b": self.skills[1],
            "seed": self.seed,
            "scene": played.name,
            "scene_hash": match_hash(played, self.limit),
            "best_of": played.match.best_of,
            "winner": None if referee.winner is None or abandoned else "ab"[referee.winner],
            "games": [list(g) for g in referee.games],
            "points": [sum(1 for p in decided if p.winner == k) for k in (0, 1)],
            "lets": len(points) - len(decided),
            "reasons": reasons,
            "mean_rally_shots": float(np.mean([p.shots for p in decided])) if decided else 0.0,
            "ticks": ticks,
            "sim_seconds": ticks * played.dt,
            "wall_seconds": time.perf_counter() - self.started if wall_seconds is None else wall_seconds,
            "record_hash": digest.hexdigest(),
            "bot_errors": [{k: v for k, v in error.items() if k != "detail"} for error in match.bot_errors],
            "stopped": match.stopped is not None or abandoned is not None,
        }
        if abandoned is not None:
            record["abandoned"] = abandoned
        return record
