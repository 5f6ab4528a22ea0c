"""The seats of a match's AI-driven bats: each one's player (a bot or an AI profile), what it is
shown, how its answer is checked, and the force law that plays it.

At a control tick a seat whose player may decide differently (a bot: always; an AI profile:
when BatAI.wakes says so, or the rally's key changed) gets a fresh observation and answers; the
answer is checked (engine.play.bot.check_action) against its arm's limits and, within its CPU time
budget, becomes the seat's plan: its row of the ctl array, an arm target that
engine.play.arm.control_bats tracks or a raw force and torque. A decision that raises, returns
something malformed or non-finite, or overruns is a fault: the seat's plan becomes the idle arm's
brake (engine.play.arm.ARM_BRAKE) and the fault is returned, for the match to record and act on
(engine.play.match.Match). The match plays a plan decision_delay ticks after it was decided.
"""
from __future__ import annotations

import math
import signal
import time
import traceback

import numpy as np
from numba import njit

from engine.physics.dtypes import BAT_DTYPE, OBSERVATION_DTYPE
from engine.physics.scene import is_bot_spec
from engine.play.bot import (A_FORCE, A_HOLD, A_SEGMENTS, ACTION_FLOATS, ACTION_FORCE, NORMAL_TOLERANCE, Bot, bot_name,
                             check_action, load_bot, new_observation, target_problem)
from engine.play.ai import SKILLS, BatAI
from engine.play.ai.profile_bot import ProfileBot
from engine.play.arm import (ARM_BRAKE, ARM_FORCE, ARM_TARGET, BAT_FLOATS, CTL_D_ANGLE, CTL_FORCE, CTL_HOLD,
                             CTL_INERTIA, CTL_K_ANGLE, CTL_KD, CTL_KIND, CTL_KP, CTL_MASS, CTL_MAX_FORCE, CTL_MAX_SPEED,
                             CTL_MAX_TORQUE, CTL_N_SEGMENTS, CTL_NORMAL, CTL_SEGMENTS, CTL_SIZE, MAX_SEGMENTS, SEG_T0,
                             SEG_T1, SEG_WIDTH, control_bats)
from engine.play.rules import Phase, next_striker

DEFAULT_BUDGET_S = 0.02  # CPU seconds a bot's decision may take, unless the bot or the match says otherwise
# A decision still running after HANG_FACTOR budgets of wall time (at least HANG_MIN_S) is
# interrupted (SIGALRM) wherever the match runs in a process's main thread: the AI worker, an
# in-process match, a tournament's or a sweep's task on the pool or Ray, an environment. So a
# bot that waits forever faults the same way, with the same match, whatever runs it.
HANG_FACTOR = 10.0
HANG_MIN_S = 0.2
_OBS_FLOATS_AT = OBSERVATION_DTYPE.fields["time"][1]  # time, ball (9), own (13), other (13): 36 float64 words
_STATE_FLOATS = 13  # a bat's pos, quat, vel, ang_vel: BAT_DTYPE's first words, engine.physics.dtypes.BAT_STATE_DTYPE


class _Overrun(BaseException):
    """Raised by SIGALRM inside a decision that did not return in time (not an Exception, so a
    bot's own `except Exception` does not swallow it)."""


def _alarm(signum, frame):
    raise _Overrun()


class HangAlarm:
    """SIGALRM after `seconds` of wall time raises _Overrun in the code it guards (None: no
    alarm). The handler and the real-time timer are the process's: whatever held them before
    (a lock's wait, a test runner's timeout) gets them back afterwards, its timer less the time
    spent here, so the guard can run anywhere in a main thread."""

    def __init__(self, seconds: float | None):
        self.seconds = seconds
        self._handler = None
        self._timer = (0.0, 0.0)
        self._started = 0.0

    def __enter__(self) -> HangAlarm:
        if self.seconds is not None:
            self._handler = signal.signal(signal.SIGALRM, _alarm)
            self._started = time.monotonic()
            self._timer = signal.setitimer(signal.ITIMER_REAL, self.seconds)
        return self

    def __exit__(self, *exc) -> None:
        if self.seconds is None:
            return
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, self._handler)
        delay, interval = self._timer
        if delay > 0.0:  # the outer timer, less the time spent here (due already: at once)
            signal.setitimer(signal.ITIMER_REAL, max(delay - (time.monotonic() - self._started), 1e-6), interval)


def _raised(exc: Exception) -> tuple[str, str]:
    """The fault of a decision that raised exc: ("raised", what and where)."""
    where = traceback.extract_tb(exc.__traceback__)[-1]
    return "raised", f"{type(exc).__name__}: {exc} ({where.filename}:{where.lineno})"


_DECIDING: list = [None]  # the decision in progress in this process: (seat, time.monotonic() at its start)


def decision_in_progress() -> tuple[str, int, float, float | None] | None:
    """The bot decision this process is in, if any: (bot name, player, seconds in act(), the
    seconds after which HangAlarm interrupts it or None). For a watchdog on another thread: a
    decision far past its interrupt is blocked where no signal reaches it (in C)."""
    current = _DECIDING[0]
    if current is None:
        return None
    seat, started = current
    return seat.name, seat.player, time.monotonic() - started, seat.hang_s


def can_interrupt() -> bool:
    """Whether this thread may set signal handlers (only the main thread of a process may)."""
    try:
        signal.signal(signal.SIGALRM, signal.getsignal(signal.SIGALRM))
    except ValueError:
        return False
    return True


def _floats(record: np.ndarray, start: int, count: int) -> np.ndarray:
    """A float64 view of `count` words of a 0-d structured array from byte `start`."""
    return record.reshape(1).view(np.uint8)[start:start + count * 8].view(np.float64)


@njit(cache=True, _nrt=False)
def _take_target(src, dst, checked=True):
    """dst's arm target (ctl rows) becomes src's, as Seat._take takes an action's, if check_action
    would pass it with room to spare (its face normal's length within half NORMAL_TOLERANCE of 1),
    or without the check if not `checked`; whether it did."""
    if checked:
        n = src[CTL_N_SEGMENTS]
        if not 0.0 <= n <= MAX_SEGMENTS:
            return False
        for i in range(CTL_HOLD, CTL_HOLD + 6):
            if not math.isfinite(src[i]):
                return False
        for i in range(CTL_SEGMENTS, CTL_SEGMENTS + int(n) * SEG_WIDTH):
            if not math.isfinite(src[i]):
                return False
        n0, n1, n2 = src[CTL_NORMAL], src[CTL_NORMAL + 1], src[CTL_NORMAL + 2]
        if abs(math.sqrt(n0 * n0 + n1 * n1 + n2 * n2) - 1.0) > NORMAL_TOLERANCE / 2:
            return False
        for k in range(int(n)):
            at = CTL_SEGMENTS + k * SEG_WIDTH
            if not src[at + SEG_T1] > src[at + SEG_T0]:
                return False
    dst[CTL_KIND] = ARM_TARGET
    for i in range(CTL_HOLD, CTL_HOLD + 6):  # hold, then normal
        dst[i] = src[i]
    dst[CTL_N_SEGMENTS] = int(src[CTL_N_SEGMENTS])
    for i in range(CTL_SEGMENTS, dst.shape[0]):
        dst[i] = src[i]
    return True


# A seat's decision gate (Players.gates, gate_open) when it has not decided yet: no key equals it.
NO_KEY = (-1, -1, -1, -1)


def gate_open(key: tuple, now: float, keys, dues, ends) -> bool:
    """Would Players.decide let a seat decide now, from the seats' gates (Players.gates: each
    seat's key at its last decision and its wakes; arrays, or a list of key tuples and lists of
    floats)? Seat.needs_decision's test, for a caller that holds only the gates (the physics
    worker, processes.workers.ai_driver)."""
    for k in range(len(dues)):
        if now >= dues[k] or now > ends[k] or key != tuple(keys[k]):
            return True
    return False


def decision_key(rally) -> tuple[int, int, int, int]:
    """What a decision depends on besides the clock and the ball, from a RALLY_DTYPE record:
    (rally, shots, the player to strike next, whether that strike is a service)."""
    phase, server, striker = int(rally["phase"]), int(rally["server"]), int(rally["striker"])
    return (int(rally["rally"]), int(rally["shots"]), next_striker(phase, server, striker),
            int(phase == Phase.WAITING_SERVE))


class Seat:
    """One AI-driven bat's player.

    Args:
        bot: the engine.play.bot.Bot (set up here). name: for messages. player: its bat (0 or 1).
        scene: the match scene. mass: kg, inertia: kg m^2, of its bat. ctl: its (CTL_SIZE,) row
            of Players.ctl. budget_s: CPU s per decision (the bot's own budget_s wins).
        interrupt: stop a hung decision with SIGALRM (HangAlarm); False where signals cannot
            be used (a thread other than the main one).
    """

    def __init__(self, bot: Bot, name: str, player: int, scene, mass: float, inertia: float, ctl: np.ndarray,
                 budget_s: float | None, interrupt: bool, spec: str | None = None):
        if bot.arm not in SKILLS:
            raise ValueError(f"bot {name}: arm {bot.arm!r} must be one of the profiles {', '.join(SKILLS)}")
        self.bot, self.name, self.player, self.spec = bot, name, player, spec
        self.profile = isinstance(bot, ProfileBot)
        arm = SKILLS[bot.arm]
        self.max_force, self.max_torque = arm.max_force_n, arm.max_torque_nm
        self.mass = mass
        self.ctl = ctl
        self.ctl_start = np.zeros(CTL_SIZE)  # the row before the first decision: the arm's constants, the bat's pose
        start = self.ctl_start
        start[[CTL_MASS, CTL_INERTIA, CTL_KP, CTL_KD, CTL_K_ANGLE, CTL_D_ANGLE]] = (
            mass, inertia, BatAI.KP, BatAI.KD, BatAI.K_ANGLE, BatAI.D_ANGLE)
        start[[CTL_MAX_FORCE, CTL_MAX_TORQUE, CTL_MAX_SPEED]] = arm.max_force_n, arm.max_torque_nm, arm.max_speed
        end_sign = -1 if player == 0 else 1
        start[CTL_HOLD:CTL_HOLD + 3] = scene.bats[player].pos
        start[CTL_NORMAL:CTL_NORMAL + 3] = (-end_sign, 0.0, 0.0)
        start[CTL_KIND] = ARM_TARGET
        self.budget_s = None if self.profile else (bot.budget_s if bot.budget_s is not None else budget_s)
        self.interrupt = interrupt and self.budget_s is not None and math.isfinite(self.budget_s)
        self.hang_s = max(HANG_MIN_S, HANG_FACTOR * self.budget_s) if self.interrupt else None
        self.obs = new_observation()
        self.view = self.obs.view()
        self.view.flags.writeable = False  # the bot's: it reads, never writes, what the seat shows
        self.obs_floats = _floats(self.obs, _OBS_FLOATS_AT, 36)
        self._start()

    def _start(self) -> None:
        """The seat before its first decision."""
        self.ctl[:] = self.ctl_start
        self.key = None  # the decision key of the last decision
        self.decisions = 0
        self.faults = 0
        self.act_seconds = 0.0  # CPU time of the bot's decisions

    def renew(self, seed: int) -> None:
        """An AI profile's seat as make_players makes it for a match of this seed (ProfileBot.renew)."""
        self.bot.renew(seed * 1000 + self.player)
        self._start()

    @property
    def kind(self) -> int:
        """What its arm plays: engine.play.arm.ARM_TARGET, ARM_FORCE or ARM_BRAKE."""
        return int(self.ctl[CTL_KIND])

    def needs_decision(self, key, now: float) -> bool:
        """Whether the player may answer differently now: always for a bot; for an AI profile,
        when the key changed or the clock reached its wakes (engine.play.ai.BatAI.wakes)."""
        if not self.profile or self.kind != ARM_TARGET or key != self.key:
            return True
        due, end = self.bot.wakes()
        return now >= due or now > end

    def wakes(self) -> tuple[float, float]:
        """(due, end) s: until the first `now >= due` or `now > end` no decision of this seat can
        change anything (-inf, -inf: ask at every control tick)."""
        if not self.profile or self.kind != ARM_TARGET:
            return -math.inf, -math.inf
        return self.bot.wakes()

    def observe(self, tick: int, now: float, ball_flat, floats: np.ndarray, rally, key) -> np.ndarray:
        """Write the observation of a state into the seat's record; returns the bot's read-only view.

        floats: (n_bats, BAT_FLOATS) every bat's record as float64. rally: the RALLY_DTYPE record.
        key: (rally, shots, to_strike, serve), Players.control's.
        """
        obs, o = self.obs, self.obs_floats
        me = self.player
        obs["tick"] = tick
        o[0] = now
        o[1:10] = ball_flat
        o[10:23] = floats[me, :_STATE_FLOATS]
        o[23:36] = floats[1 - me, :_STATE_FLOATS]
        obs["score"], obs["games_won"] = rally["score"], rally["games_won"]
        obs["phase"], obs["server"], obs["shots"], obs["rally"] = rally["phase"], rally["server"], key[1], key[0]
        obs["to_strike"] = key[2]
        return self.view

    def decide(self, tick: int, now: float, ball_flat, floats: np.ndarray, rally, key) -> tuple | None:
        """Show the state (observe), take the answer: the fault (player, fault, detail) or None.
        An AI profile's BatAI reads the state itself (ProfileBot.act's doubles, without the
        observation's record in between) and its arm target is checked as a bot's action is."""
        if self.profile:
            return self._decide_profile(now, ball_flat, floats, key)
        self.observe(tick, now, ball_flat, floats, rally, key)
        self.key = key
        self.decisions += 1
        fault = detail = None
        started = time.thread_time()
        try:
            _DECIDING[0] = (self, time.monotonic())
            with HangAlarm(self.hang_s if self.interrupt else None):
                action = self.bot.act(self.view)
        except _Overrun:
            fault, detail = "overran", f"act() had not returned after {self.hang_s:g} s: interrupted"
        except Exception as exc:  # noqa: BLE001 - whatever a bot raises is its fault, reported, never fatal
            fault, detail = _raised(exc)
        finally:
            _DECIDING[0] = None
        used = time.thread_time() - started
        self.act_seconds += used
        if fault is None and self.budget_s is not None and used > self.budget_s:
            fault, detail = "overran", f"act() took {used * 1e3:.1f} ms of CPU, its budget is {self.budget_s * 1e3:g} ms"
        if fault is None:
            problem = check_action(action, self.max_force, self.max_torque)
            if problem is None:
                self._take(action)
                return None
            fault, detail = problem
        return self._fault(fault, detail)

    def _fault(self, fault: str, detail: str) -> tuple:
        """A decision that went wrong: counted, the idle arm's brake until the next good one."""
        self.faults += 1
        self.ctl[CTL_KIND] = ARM_BRAKE
        return self.player, fault, detail

    def _decide_profile(self, now: float, ball_flat, floats: np.ndarray, key) -> tuple | None:
        """decide() of an AI profile: ProfileBot.act and _take without the observation and the
        action records, the same doubles into the same ctl row."""
        me = self.player
        self.key = key
        self.decisions += 1
        ai = self.bot.ai
        started = time.thread_time()
        try:
            _DECIDING[0] = (self, time.monotonic())
            ai.decide(now, ball_flat, floats[me], (key[0], key[1]), key[2] == me, key[3] == 1, self.bot.end_sign)
            fault = None
        except Exception as exc:  # noqa: BLE001 - as a bot's: reported, never fatal
            fault, detail = _raised(exc)
        finally:
            _DECIDING[0] = None
        self.act_seconds += time.thread_time() - started
        if fault is None:
            src = ai._ctl
            if _take_target(src, self.ctl):
                return None
            n_segments = src[CTL_N_SEGMENTS]  # the rare target near a limit, or wrong: as check_action says
            if not math.isfinite(n_segments):
                problem = "malformed", f"n_segments {n_segments}: must be in 0 .. {MAX_SEGMENTS}"
            else:
                problem = target_problem(src[CTL_HOLD:CTL_HOLD + 6], src[CTL_SEGMENTS:], int(n_segments))
            if problem is None:
                _take_target(src, self.ctl, False)
                return None
            fault, detail = problem
        return self._fault(fault, detail)

    def state(self) -> dict:
        """What the seat decides on, as plain data (load_state): its own counts, and an AI profile's
        BatAI.state (its plan is its row of Players.ctl). A bot's own objects are its own: they are
        not kept."""
        return {"key": self.key, "decisions": self.decisions, "faults": self.faults, "act_seconds": self.act_seconds,
                "ai": self.bot.ai.state() if self.profile else None}

    def load_state(self, state: dict) -> None:
        """Become the seat whose state() this is (a bot keeps the objects it has)."""
        self.key = state["key"]
        self.decisions, self.faults, self.act_seconds = state["decisions"], state["faults"], state["act_seconds"]
        if self.profile:
            self.bot.ai.load_state(state["ai"])

    def _take(self, action) -> None:
        """The checked action becomes the seat's plan: its ctl row's arm target, or its raw force."""
        values = np.frombuffer(action, np.float64, ACTION_FLOATS) if isinstance(action, np.void) else \
            _floats(action, 0, ACTION_FLOATS)
        ctl = self.ctl
        if int(action["kind"]) == ACTION_FORCE:
            ctl[CTL_KIND] = ARM_FORCE
            ctl[CTL_FORCE:CTL_FORCE + 6] = values[A_FORCE:A_FORCE + 6]
            return
        ctl[CTL_KIND] = ARM_TARGET
        ctl[CTL_HOLD:CTL_HOLD + 6] = values[A_HOLD:A_HOLD + 6]  # hold, then normal
        ctl[CTL_N_SEGMENTS] = int(action["n_segments"])
        ctl[CTL_SEGMENTS:] = values[A_SEGMENTS:]


class Players(dict):
    """{player: Seat} of a match's AI-driven bats; their arm targets are the rows of one ctl
    array, played for all of them in one numba call (engine.play.arm.control_bats)."""

    def __init__(self, seats: dict[int, Seat], ctl: np.ndarray, maker: SeatMaker | None = None):
        super().__init__(seats)
        self.maker = maker
        self.players = np.array(list(seats), dtype=np.int64)
        self.ctl = ctl
        self._bats = None  # the bats array last seen, and its float64 view
        self._floats = None
        self.decided = False  # whether a seat decided at the last decide(): otherwise nothing changed

    @property
    def thinkers(self) -> list[BatAI]:
        """The AI profiles' BatAI (the AI worker spreads their thinking between turns)."""
        return [seat.bot.ai for seat in self.values() if seat.profile]

    def bat_floats(self, bats: np.ndarray) -> np.ndarray:
        """(n_bats, BAT_FLOATS) float64 view of a BAT_DTYPE array (made once for the same array)."""
        if bats is not self._bats:
            if bats.dtype != BAT_DTYPE or bats.ndim != 1 or not bats.flags.c_contiguous:
                raise TypeError(f"Players: bats must be a contiguous 1-D engine.physics.dtypes.BAT_DTYPE array, got "
                                f"dtype {bats.dtype}, shape {bats.shape}")
            self._floats = bats.view(np.float64).reshape(len(bats), BAT_FLOATS)
            self._bats = bats
        return self._floats

    def decide(self, tick: int, now: float, ball_flat: np.ndarray, bats: np.ndarray, rally, before=None) -> list:
        """The decisions of every seat that may decide differently now: their plans (rows of ctl).

        Args:
            tick, now: the state's tick and time (s). ball_flat: (9,) the ball. bats: the
                (n_bats,) BAT_DTYPE array. rally: its RALLY_DTYPE record.
            before: called once before the first seat decides, if one does (a speculating AI
                worker keeps its way back there: processes.workers.ai.TakeBacks).

        Returns:
            The faults of this control tick: [(player, fault, detail)], engine.play.bot.FAULTS names.
        """
        floats = self.bat_floats(bats)
        key = decision_key(rally)
        faults = []
        decided = False
        for seat in self.values():
            if seat.needs_decision(key, now):
                if not decided and before is not None:
                    before()
                decided = True
                fault = seat.decide(tick, now, ball_flat, floats, rally, key)
                if fault is not None:
                    faults.append(fault)
        self.decided = decided
        return faults

    def gates(self, keys: np.ndarray, dues: np.ndarray, ends: np.ndarray) -> None:
        """Each seat's decision gate after the decisions so far, in seat order: its key at its last
        decision (NO_KEY: none yet) into keys[k] (4 ints) and its wakes (Seat.wakes: -inf, -inf
        for a seat asked at every control tick) into dues[k], ends[k] (s). gate_open(key, now,
        ...) is then decide()'s test of whether anybody decides."""
        for k, seat in enumerate(self.values()):
            keys[k] = NO_KEY if seat.key is None else seat.key
            dues[k], ends[k] = seat.wakes()

    def renew(self, seed: int) -> None:
        """Become the Players that make_players makes for a match of this seed, keeping what can be
        kept: an AI profile's seat is renewed (Seat.renew), a bot's seat is made anew (a bot's
        own objects are its own)."""
        if self.maker is None:
            raise ValueError("Players.renew: these players were not made by make_players")
        for k, (player, seat) in enumerate(list(self.items())):
            if seat.profile:
                seat.renew(seed)
            else:
                self[player] = self.maker.seat(seat.spec, player, self.ctl[k], seed)
        self.decided = False

    def use_scratch(self, scratch: tuple) -> None:
        """The AI profiles think in `scratch` (BatAI.use_scratch)."""
        for ai in self.thinkers:
            ai.use_scratch(scratch)

    def state(self) -> dict:
        """Every seat's state() and the arm targets, picklable: the same scene's Players that loads
        it (load_state) decides on as this one would, a bot's own objects aside."""
        return {"ctl": self.ctl.copy(), "seats": {player: seat.state() for player, seat in self.items()}}

    def load_state(self, state: dict) -> None:
        """Become the Players whose state() this is (the same scene's, made by make_players)."""
        self.ctl[:] = state["ctl"]
        for player, seat in self.items():
            seat.load_state(state["seats"][player])

    def wakes(self) -> tuple[float, float]:
        """(due, end) s: the earliest of every seat's wakes."""
        due = end = math.inf
        for seat in self.values():
            seat_due, seat_end = seat.wakes()
            due, end = min(due, seat_due), min(end, seat_end)
        return due, end

    @property
    def stats(self) -> dict:
        """Per end: an AI profile's BatAI.stats; a bot's decisions, faults and CPU seconds."""
        return {"ab"[p]: dict(seat.bot.ai.stats) if seat.profile else
                {"bot": seat.name, "decisions": seat.decisions, "faults": seat.faults, "act_s": seat.act_seconds}
                for p, seat in self.items()}

    def warm_up(self) -> None:
        """BatAI.warm_up of each AI profile, and control_bats."""
        for ai in self.thinkers:
            ai.warm_up()
        bats = np.zeros(max(self, default=0) + 1, BAT_DTYPE)
        bats["quat"] = (1.0, 0.0, 0.0, 0.0)
        ctl = self.ctl.copy()
        ctl[:, CTL_NORMAL] = 1.0
        control_bats(0.0, bats.view(np.float64).reshape(len(bats), BAT_FLOATS), ctl, self.players,
                     np.zeros((len(bats), 6)))


def make_players(scene, model, seed: int, control_every: int, delay: int, eager: bool = True,
                 budget_s: float | None = DEFAULT_BUDGET_S, interrupt: bool | None = None) -> Players:
    """The seat of every bat the scene gives a player (bat.skill: an AI profile or a bot spec).

    An AI profile's BatAI is seeded from the match seed and its player (seed * 1000 + player), a
    bot's rng likewise. eager=False: the profiles think a stroke out only in the steps they are
    given (the AI worker); the same strokes. Raises ValueError naming a bot that cannot be
    loaded, made or set up.
    """
    chosen = [(i, bat.skill) for i, bat in enumerate(scene.bats) if bat.skill is not None]
    ctl = np.zeros((len(chosen), CTL_SIZE))
    if interrupt is None:
        interrupt = can_interrupt()
    maker = SeatMaker(scene, model, control_every, delay, eager, budget_s, interrupt)
    return Players({player: maker.seat(spec, player, ctl[k], seed) for k, (player, spec) in enumerate(chosen)}, ctl,
                   maker)


class SeatMaker:
    """make_players's seats of one scene: Seat(spec, player, its ctl row, match seed)."""

    def __init__(self, scene, model, control_every: int, delay: int, eager: bool, budget_s: float | None,
                 interrupt: bool):
        self.scene, self.model = scene, model
        self.control_every, self.delay, self.eager = control_every, delay, eager
        self.budget_s, self.interrupt = budget_s, interrupt

    def seat(self, spec: str, player: int, ctl: np.ndarray, seed: int) -> Seat:
        scene, model = self.scene, self.model
        if is_bot_spec(spec):
            name = bot_name(spec)
            try:
                bot = load_bot(spec)()
            except ValueError:
                raise
            except Exception as exc:
                raise ValueError(f"bot {name}: making it raised {type(exc).__name__}: {exc}") from exc
        else:
            name = spec
            bot = ProfileBot(model, player, SKILLS[spec], spec, seed=seed * 1000 + player,
                             control_every=self.control_every, delay=self.delay, eager=self.eager)
        end_sign = -1 if player == 0 else 1
        bot.player, bot.end_sign, bot.latency = player, end_sign, self.delay * model.dt
        bot.normal = np.array([-end_sign, 0.0, 0.0])
        # seeded alike: a profile's is its BatAI's, the same generator (a profile draws only through its BatAI)
        bot.rng = bot.ai.rng if isinstance(bot, ProfileBot) else np.random.default_rng(seed * 1000 + player)
        try:
            bot.setup(player, scene)
        except Exception as exc:
            raise ValueError(f"bot {name}: setup() raised {type(exc).__name__}: {exc}") from exc
        return Seat(bot, name, player, scene, float(model.bat_mass[player]), float(model.bat_inertia[player][0]),
                    ctl, self.budget_s, self.interrupt, spec)
