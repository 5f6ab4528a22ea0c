"""A speculating physics worker (RunOptions.speculate): it steps on past the ball's runs near the
net before the net worker has answered them, as if the net touched none, and goes back where
one did, the way rollback netcode does (GGPO's save, load and advance: a checkpoint is one
record's copy, going back is loading it and stepping again with the answer now known).

Without speculation the physics waits for every run's answer, and a struck net's ring keeps the
net worker hundreds of ticks behind: the next time the ball passes the net the physics waits
for all of them (docs/match-timeline.png's long red blocks). Speculating, it goes on, and so does
the AI, deciding from the states stepped on; the net confirms in order, on the other core.

What makes it exact:
- SpeculativeNet posts each run on a queue (processes.runtime.handoff.TurnQueue, `net_queue`)
  and says "no touch"; the net worker answers the runs in order and halts at a touch.
- Before each Match.tick call that may post a run the loop keeps a checkpoint (Match.checkpoint,
  AIDriver.checkpoint); at a touch it loads the checkpoint of the touching run's call, tells the
  stand-in the answer (so stepping again takes it instead of guessing), takes back the runs,
  grants and AI turns posted since (the net then goes on: its epoch moves) and steps again.
- Nothing the physics publishes (events, snapshots, points) is a guess: each is published once
  every run before it is confirmed.
- The AI worker keeps a way back from its decisions on states not yet final
  (processes.workers.ai.TakeBacks), and the turns taken back are posted again as new turns.

What keeps it cheap: a guess is only as deep as the net is behind, and a wrong one is stepped
again. Where the ball flies into the net (its centre crosses the net's plane inside the net as
built, grown by the radii) the touch is certain: the loop waits there, asleep, until the runs
before it are answered, and that run is waited for (SpeculativeNet.heading_through); after any
touch the next runs are waited for until one comes back untouched (a ball resting on the net
touches it every tick).

Restarts: a snapshot is published only where every run before it is confirmed, and beside it
the cut (processes.workers.cut): the runs posted before it and the AI driver's turns in flight
there. A restarted physics resumes from the snapshot, takes back the AI turns posted after the
newest one confirmed and sends the net back to its state after the cut's last run (SpeculativeNet.go_back); a
restarted net goes on from its state after the last run it answered (processes.workers.net),
a restarted AI from its state kept and the decisions journalled since (processes.workers.ai).

The runs that keep every tick (traces, frames), serve remote players or seat a bot are refused
(options.speculation_refusal).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from engine.physics.equipment import BALL_RADIUS
from net_kernel import NO_CONTACT, NetContact, NetSim
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.runtime.timeline import WAIT_NET, WORK, Timeline
from processes.workers.cut import Cuts
from processes.workers.layout import SPEC_BACK, SPEC_EPOCH, SPEC_GRANTED, SPEC_RUNS
from processes.workers.options import RunOptions
from processes.workers.remote_net import KnownNet

NET_GIVE_UP_S = 60.0  # the longest wait for a run's answer, a restart of the net worker included
# Ticks between two snapshots (and their cuts) at most while nothing else changes: a restarted
# physics steps again at most this many ticks; a point decided is published at once, and so is
# a snapshot SPEC_RUNS // 2 runs after the last (the net keeps its states after NET_STATES runs).
SNAPSHOT_EVERY_TICKS = 256


class SpeculativeNet(KnownNet):
    """The speculating physics worker's stand-in for NetSim (engine.physics.world.NetStepper):
    step_run posts the run and answers "no touch" (or, stepping again after a go-back, the net's
    answer); poll() reads the net's answers in order and names the first run the net touched.

    What it knows of the net (asleep, in its tail, its box and bound) comes from the newest
    confirmed answer, carried forward over the runs in flight as the net would be if they
    touched nothing: a sleeping net stays asleep, a bound still holds, and a net in its tail with
    the ball near leaves it (then nothing more is known). A wrong guess of this kind costs a run
    more, never a bit: the net steps every run as NetSim.step would.
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, world, local: NetSim):
        super().__init__(world, local)
        self.control = control
        self.timeline: Timeline | None = None
        self.handoff_s = options.handoff_s
        self.queue = options.handles.net_queue.attach(arena["net_queue"].array)
        self.runs = arena["net_runs"].array
        self.answers = arena["net_answers"].array
        self.words = memoryview(arena["net_spec"].array.view("<i8")).cast("B").cast("q")
        self.in_flight: deque = deque()  # (number, first tick, ticks) of the runs posted, not yet confirmed
        self.known: dict[int, tuple] = {}  # first tick -> the net's answer, for the run stepped again
        # The net as built: a ball whose centre passes its plane (x = 0) inside this (y, z) span
        # touches it for sure, so that run is waited for instead of guessed.
        built, reach = local.box, BALL_RADIUS + local.knot_radius
        self.through = (float(built[0, 1]), float(built[1, 1]), float(built[0, 2]), float(built[1, 2]) + reach)
        # After a touch the next runs are waited for, as without speculation, until one comes back
        # untouched: a ball resting on the net touches it every tick, and each guess would go back.
        self.synchronous = False
        self._knowledge: tuple | None = None  # the tuple `knowledge` gave last (None: changed since)
        self._none = np.zeros(3)
        self.waits = 0.0
        self.ball_ticks = self.runs_posted = self.free_ticks = self.turns_again = 0
        self.rollbacks = self.ticks_again = 0  # go-backs, and the ticks they stepped again

    @property
    def free(self) -> int:
        """Runs that may still be posted before the queue is full."""
        return SPEC_RUNS - 1 - (self.queue.posted - self.queue.answered)

    def _grant(self, tick: int) -> None:
        if tick > self.words[SPEC_GRANTED]:
            self.words[SPEC_GRANTED] = tick

    def step_free(self, ticks: int) -> None:
        if ticks > 0:
            self._grant(int(self.world["tick"]))
            self.free_ticks += ticks
            if not self._sleeping and not 0 <= self._tail_until:
                self.queue.nudge()  # an awake net's ticks: the net worker steps them on the other core

    def step_run(self, ball: np.ndarray, ball_radius: float, ball_inv_mass: float,
                 free_outside: np.ndarray) -> tuple[int, NetContact]:
        local = self.local
        count = len(ball)
        first = int(self.world["tick"]) - count
        # Stepped again after a go-back: the touched run's answer, from the tick it started at then
        # (what is known of the net has changed since, and with it where a run would start now).
        for start, (taken, toi, impulse, offset, after) in self.known.items():
            if first <= start < first + count:
                self.known.clear()
                self.knowledge = after
                return start - first + taken, NetContact(toi, impulse, offset)
        j = self.far_ticks(ball, first, ball_radius)
        self.free_ticks += j
        tick = first + j
        self._grant(tick)
        if j == count:
            self._none[:] = 0.0
            return count, NetContact(NO_CONTACT, self._none, self._none)
        queue = self.queue
        if self.free <= 0:
            raise RuntimeError(f"speculation: {SPEC_RUNS - 1} runs in flight fill the queue (processes.workers."
                               "speculation's loop waits before posting another)")
        number = queue.posted + 1
        slot = self.runs[number % SPEC_RUNS]
        slot["tick"], slot["count"] = tick, count - j
        slot["ball"][:count - j] = ball[j:]
        slot["radius"], slot["inv_mass"] = ball_radius, ball_inv_mass
        queue.post()
        self.runs_posted += 1
        self.ball_ticks += count - j
        if (self.synchronous or self._through(ball[j:], local.dt)) and not self.in_flight:
            taken, contact = self._answer_now(number)
            return j + taken, contact
        self.in_flight.append((number, tick, count - j))
        if self._tail_until > tick:  # the ball near a ringing tail: the net leaves it, unknown from here
            self._tail_until, self._bounded = -1, False
            self._knowledge = None
        self._none[:] = 0.0
        return count, NetContact(NO_CONTACT, self._none, self._none)

    def heading_through(self, ball_flat: np.ndarray, ticks: int) -> bool:
        """Will the ball's centre (ball_flat: pos, vel) pass the net's plane inside the net as built
        within `ticks` ticks, flying straight? Then the net touches it for sure, and whatever the
        physics steps past that run on a guess would be stepped again."""
        x, vx = float(ball_flat[0]), float(ball_flat[3])
        if vx == 0.0 or not 0.0 <= -x / vx <= ticks * self.local.dt:
            return False
        t = -x / vx
        y, z = float(ball_flat[1]) + float(ball_flat[4]) * t, float(ball_flat[2]) + float(ball_flat[5]) * t
        y_lo, y_hi, z_lo, z_hi = self.through
        return y_lo < y < y_hi and z_lo < z < z_hi

    def _through(self, ball: np.ndarray, dt: float) -> bool:
        """Does the ball's centre pass the net's plane inside the net as built in these ticks?"""
        y_lo, y_hi, z_lo, z_hi = self.through
        for k in range(len(ball)):
            x, y, z = ball[k, 0]
            if x * (x + ball[k, 1, 0] * dt) <= 0.0 and y_lo < y < y_hi and z_lo < z < z_hi:
                return True
        return False

    def _answer_now(self, number: int) -> tuple[int, NetContact]:
        """Wait for run `number`'s answer (nothing before it in flight) and take it as it is, as
        the stand-in of a run that does not speculate does; a touch ends nothing here (the net
        goes on at once), an untouched run ends the waiting."""
        self.in_flight.append((number, -1, 0))
        self.wait_oldest()
        self.in_flight.clear()
        answer = self.answers[number % SPEC_RUNS]
        self._learn(answer)
        toi = float(answer["toi"])
        if toi != NO_CONTACT:
            self.words[SPEC_EPOCH] += 1  # the net halted at the touch: nothing to take back, go on
        else:
            self.synchronous = False
        return int(answer["taken"]), NetContact(toi, answer["impulse"].copy(), answer["offset"].copy())

    def poll(self) -> int | None:
        """Read the answers come in: confirm the runs the net did not touch (in order) and return
        the number of the first it touched, or None."""
        answered = self.queue.answered
        while self.in_flight and self.in_flight[0][0] <= answered:
            number, tick, count = self.in_flight[0]
            answer = self.answers[number % SPEC_RUNS]
            if int(answer["run"]) != number:
                raise RuntimeError(f"speculation: run {number}'s answer slot holds run {int(answer['run'])}")
            if float(answer["toi"]) != NO_CONTACT or int(answer["taken"]) < count:
                return number
            self.in_flight.popleft()
            if not self.in_flight:  # the newest run: what the net is now, with nothing guessed after it
                self._learn(answer)
        return None

    def wait_oldest(self) -> None:
        """Wait (bounded, with heartbeats) for the answer of the oldest run in flight."""
        number = self.in_flight[0][0]
        if self.queue.answered >= number:
            return
        started = time.perf_counter()
        if self.timeline is not None:
            self.timeline.mark(WAIT_NET)
        self.queue.wait_answered(number, self.handoff_s, NET_GIVE_UP_S, self._beat)
        if self.timeline is not None:
            self.timeline.mark(WORK)
        self.waits += time.perf_counter() - started

    def _beat(self, _turn: int) -> None:
        self.control.beat(int(self.world["tick"]))
        self.turns_again += 1

    @property
    def knowledge(self) -> tuple:
        """What is known of the net (for a checkpoint): asleep, the tail's end, box, bounded,
        bound; one tuple until it changes."""
        if self._knowledge is None:
            self._knowledge = (self._sleeping, self._tail_until, self.box.copy(), self._bounded, self.bound.copy())
        return self._knowledge

    @knowledge.setter
    def knowledge(self, known: tuple) -> None:
        self._sleeping, self._tail_until, box, self._bounded, bound = known
        self.box[:] = box
        self.bound[:] = bound
        self._knowledge = known

    def take_back(self, number: int, knowledge: tuple) -> int:
        """The net touched run `number` (the oldest in flight): keep its answer for the step
        again, go back to what was known of the net at the checkpoint (`knowledge`: the step
        again then hands the net the same runs), take back the runs and grants after it and let
        the net go on; returns the tick after the touch (where the net halted)."""
        answer = self.answers[number % SPEC_RUNS]
        _, tick, _ = self.in_flight[0]
        taken = int(answer["taken"])
        self._learn(answer)
        after = self.knowledge
        self.known = {tick: (taken, float(answer["toi"]), answer["impulse"].copy(), answer["offset"].copy(), after)}
        self.knowledge = knowledge
        self.in_flight.clear()
        self.queue.rewind(number)
        halted = tick + taken
        self.words[SPEC_GRANTED] = halted
        self.words[SPEC_EPOCH] += 1  # last: the net worker goes on from here
        self.rollbacks += 1
        self.synchronous = True  # the ball may touch on: wait for the next run's answer
        return halted

    def _learn(self, answer) -> None:
        self._knowledge = None
        self.learn(answer["sleeping"], answer["tail_until"], answer["box"], answer["bounded"], answer["bound"])

    def go_back(self, runs: int, tick: int) -> None:
        """A restarted physics worker resumes at `tick`, `runs` runs near the net posted before it
        (the snapshot's cut): the net goes back to its state after the last of them, the ticks
        from there to `tick` granted free (as they were), and the runs posted after it are taken
        back; waits (bounded, with heartbeats) until the net is there."""
        words, queue = self.words, self.queue
        words[SPEC_GRANTED] = tick
        queue.withdraw(runs)  # first: from here on no net worker takes a run past it
        words[SPEC_BACK] = runs
        queue.wait_for(lambda: words[SPEC_BACK] < 0 and queue.answered == runs,
                       f"the net did not go back to its state after run {runs}", self.handoff_s, NET_GIVE_UP_S,
                       lambda: self.control.beat(tick))
        words[SPEC_EPOCH] += 1  # last: the net worker goes on from here

    @property
    def runs_stepped(self) -> int:
        """The runs posted whose ticks the physics has stepped: all of them, but for a touched
        run that a go-back steps again (its answer kept in `known`)."""
        return self.queue.posted - (1 if self.known else 0)

    def stop(self) -> float:
        """The run is over (every run answered): tell the net worker; the wall time waited for it."""
        self.queue.stop()
        self.words.release()
        return self.waits


@dataclass
class Published:
    """What the speculating loop has published so far: the events held and the points up to
    which, the tick confirmed last, and the snapshot's tick, the runs posted before it and the
    oldest AI turn its cut needs (a restart goes back there)."""

    events: int
    points: int
    tick: int
    snapshot_tick: int
    snapshot_runs: int
    first_turn: int


class Checkpoints:
    """The speculating loop's way back: a checkpoint before each Match.tick call that posted a run
    (the match's and the AI driver's), dropped once the run is confirmed, and what the physics
    published not yet (events, points), held until every run before it is confirmed."""

    def __init__(self):
        # (run number, tick, Match.checkpoint, AIDriver.checkpoint or None, events held, what was known
        # of the net, the runs posted before the call)
        self.kept: deque = deque()
        self.events: list = []  # (tick after the call, its events' copy) not yet published

    def add(self, run: int, tick: int, match_cp, driver_cp, knowledge: tuple, runs_before: int) -> None:
        self.kept.append((run, tick, match_cp, driver_cp, len(self.events), knowledge, runs_before))

    def confirmed_to(self, in_flight: deque) -> tuple | None:
        """Drop the checkpoints of the runs confirmed (no longer in flight); the oldest kept one, or None."""
        oldest = in_flight[0][0] if in_flight else None
        while self.kept and (oldest is None or self.kept[0][0] < oldest):
            self.kept.popleft()
        return self.kept[0] if self.kept else None

    def take(self, run: int) -> tuple:
        """The checkpoint of run `run`'s call; it and every later one are dropped, and so are the
        events held since it."""
        while self.kept[-1][0] > run:
            self.kept.pop()
        checkpoint = self.kept.pop()
        if checkpoint[0] != run:
            raise RuntimeError(f"speculation: no checkpoint for run {run}")
        del self.events[checkpoint[4]:]
        return checkpoint


def run_speculating(control: Control, match, net: SpeculativeNet, driver, out, points_log: np.ndarray,
                    n_ticks: int, cuts: Cuts, resumed: bool, faults=None) -> float:
    """The speculating physics worker's loop over its Match (lockstep) until n_ticks or the
    match's end, every run confirmed; returns the wall time of its own work and waits.

    out: the worker's publisher (events, snapshots); driver: its AIDriver (None: no AI);
    points_log: the run's point log (POINT_DTYPE in shared memory); cuts: the run's cuts, the
    one at the match's tick written (a fresh run) or read (resumed: the match restored from the
    snapshot, the driver from the cut); faults: the worker's FaultPlan (tests: end at the first
    call at or after its crash tick that leaves runs in flight).
    """
    from engine.play.match import point_row

    kept = Checkpoints()
    tick = match.current_tick
    runs, _, driver_cp = cuts.read(tick) if resumed else (0, None, None)  # the runs posted before the snapshot
    if resumed:
        net.go_back(runs, tick)
    point_ticks = [tick] * len(match.referee.points)  # the tick after the call that decided each point
    published = Published(0, len(match.referee.points), tick, tick, runs, _first_turn(driver_cp, driver))
    ai_room = len(driver.views) - 2 * (match.delay // match.ai_every) - 4 if driver is not None else 0
    busy = 0.0
    while True:
        t0 = time.perf_counter()
        touched = net.poll()
        if touched is not None:
            _, back_to, match_cp, driver_cp, _, knowledge, _ = kept.take(touched)
            net.take_back(touched, knowledge)
            match.rollback(match_cp)
            del point_ticks[match_cp[1]:]
            if driver is not None:
                driver.rollback(driver_cp)
            net.ticks_again += tick - back_to
            tick = back_to
            busy += time.perf_counter() - t0
            continue
        oldest = kept.confirmed_to(net.in_flight)
        ending = (tick >= n_ticks or match.over) and not net.in_flight
        _publish_confirmed(out, match, kept, oldest, points_log, published, point_ticks, point_row, cuts,
                           (net.runs_stepped, driver), ending, ai_room)
        if driver is not None:
            driver.confirm(oldest[3][2] if oldest is not None else driver.queue.posted)
        # A restart goes back to the cut: the AI turns from its oldest on must stay in the rings.
        if tick >= n_ticks or match.over or net.free < 2 or (
                driver is not None and net.in_flight and driver.queue.posted - published.first_turn > ai_room):
            if not net.in_flight:
                busy += time.perf_counter() - t0
                break  # the end, every run confirmed
            net.wait_oldest()
            busy += time.perf_counter() - t0
            continue
        if net.in_flight and net.heading_through(match.state.ball_flat, match.ai_every):
            # The ball flies into the net: a guess past it would be stepped again; wait (asleep:
            # the net and the AI have both cores) until every run before it is answered.
            net.wait_oldest()
            busy += time.perf_counter() - t0
            continue
        match_cp = match.checkpoint()
        driver_cp = driver.checkpoint() if driver is not None else None
        knowledge = net.knowledge
        posted = net.queue.posted
        before = tick
        match.tick(n_ticks - tick)
        tick += match.ticks_done
        while len(point_ticks) < len(match.referee.points):
            point_ticks.append(tick)
        if net.queue.posted > posted:
            kept.add(net.queue.posted, before, match_cp, driver_cp, knowledge, posted)
        if match.n_events:
            kept.events.append((tick, match.events[:match.n_events].copy()))
        busy += time.perf_counter() - t0
        if faults is not None and net.in_flight and faults.crashes_in(-1, tick + 1):
            faults.crash(tick)  # a guess in flight: the restarted physics must send the net back
        control.beat(tick)
    return busy


def _first_turn(driver_cp, driver) -> int:
    """The oldest AI turn a cut with this AIDriver.checkpoint needs: its oldest turn in flight,
    else the next one posted (driver_cp None: a fresh run, the driver's next turn; 0: no AI)."""
    if driver_cp is None:
        return driver.queue.posted + 1 if driver is not None else 0
    pending, _, posted = driver_cp[:3]
    return pending[0][1] if pending else posted + 1


def _publish_confirmed(out, match, kept: Checkpoints, oldest, points_log: np.ndarray, published: Published,
                       point_ticks: list, point_row, cuts: Cuts, now: tuple, force: bool, ai_room: int) -> None:
    """Publish what every run before it confirms: the events and points up to the oldest
    checkpoint kept (all of them if none), and the state there as the snapshot with its cut,
    when a point was decided, SNAPSHOT_EVERY_TICKS after the last, SPEC_RUNS // 2 runs after the
    last, half the AI's room of turns after the oldest turn the last needs, or `force` (the end).
    now: (the runs stepped, the AIDriver or None), the cut if no checkpoint is kept."""
    if oldest is None:
        events_to, points_to, tick, record = len(kept.events), len(match.referee.points), match.current_tick, None
    else:
        _, tick, match_cp, driver_cp, events_to, _, runs = oldest
        record, points_to, arm = match_cp[0].view(match.state.record.dtype), match_cp[1], match_cp[2]  # Match.checkpoint
    if (tick == published.tick and events_to == published.events
            and not (force and tick != published.snapshot_tick)):
        return
    for _, events in kept.events[published.events:events_to]:
        out.publish_events(events, len(events))
    points = match.referee.points
    for k in range(published.points, points_to):
        points_log[k] = point_row(points[k], point_ticks[k])
    driver = now[1]
    if oldest is None:
        runs = now[0]
    if (force or points_to != published.points or tick - published.snapshot_tick >= SNAPSHOT_EVERY_TICKS
            or runs - published.snapshot_runs >= SPEC_RUNS // 2
            or driver is not None and driver.queue.posted - published.first_turn > ai_room // 2):
        if oldest is None:
            arm, driver_cp = match.arm, (driver.checkpoint() if driver is not None else None)
        cuts.write(tick, runs, arm, driver_cp)
        out.publish_snapshot(tick, record)
        published.snapshot_tick, published.snapshot_runs = tick, runs
        published.first_turn = _first_turn(driver_cp, driver)
    published.events, published.points, published.tick = events_to, points_to, tick
