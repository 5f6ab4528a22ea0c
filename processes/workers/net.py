"""The net worker: the cloth net (net_kernel.NetSim) in a process of its own.

Two kinds of ticks reach it from the physics worker:
- Runs of ticks with the ball in the net's reach (engine.physics.world: inside model.cloth_reach, the net
  awake or the ball near its frozen shape): the physics steps the ball's ticks of a run without
  the net, gives it the baton and waits. The ball's state at each tick's start crosses in the
  shared `net_io` record and the net's answer (how many ticks it stepped, up to the first that
  touched the ball, and that touch: time of impact, impulse, offset; whether it now sleeps, its
  box) comes back in it; the baton orders the two sides, so the record needs no lock. The
  physics keeps the ticks the net stepped and applies the answer exactly as the in-process
  engine applies NetSim.step_run's.
- Ticks with the ball out of reach (NetSim.step_free): the physics only raises `granted`, the
  tick the net may step to without the ball, nudges the worker and goes on at once. The net
  steps them while the physics works: on two cores the ringing of a struck net then costs the
  physics nothing until the ball comes back within reach, where its first hand-off waits until
  the net has caught up. A sleeping net wakes nobody.
Either way the net steps the same ticks with the same inputs as the in-process NetSim, which
keeps lockstep runs bit for bit equal to the reference.

The worker publishes its whole state (engine.physics.dtypes.net_snapshot_dtype) before and after every
run stepped with the ball and after every run of free ticks, into the two SnapshotBlocks in
turn, so the state before the last run is always kept too. That makes restarts exact: a
restarted net worker resumes from its newest state (and steps the free ticks still granted); a
restarted physics worker may ask again for the run the net has just stepped, and the net then
goes back to the state before it (in the other block). Free ticks never need going back: the
physics grants a tick only after deciding it, and decides it the same way again.
"""
from __future__ import annotations

import time

import numpy as np

from engine.physics.dtypes import net_show_dtype, net_snapshot_dtype
from engine.physics.compiled import CompiledScene
from net_kernel import NO_CONTACT, NetSim
from net_kernel.sim import compile_kernels
from processes.network.wire import NET_HZ
from processes.runtime.handoff import HandoffTimeout
from processes.runtime.shm import Arena
from processes.runtime.control import Control
from processes.runtime.timeline import IDLE, WORK, Timeline
from processes.workers.layout import (NET_BLOCKS, NET_SHOW, NET_STATES, SPEC_BACK, SPEC_EPOCH, SPEC_GRANTED, SPEC_RUNS,
                                     NetIO)
from processes.workers.options import RunOptions

FREE_BEAT_TICKS = 256  # free ticks between two heartbeats: well inside the supervisor's stall timeout


class NetShow:
    """The net as a gateway's clients see it, published into the net_show block (a run with a
    gateway): after the ticks stepped, at most once every 1/NET_HZ s of match time, and whenever
    the net falls asleep or wakes. In the net's linear tail that is the tail's knots at the tick
    (NetSim.knot_pos rebuilds them from its modes); the physics nudges the worker every
    remote_net.TAIL_NUDGE_TICKS then, so the picture stays that close behind. The gateway only
    reads it: the net's physics runs in this process alone."""

    def __init__(self, block, n_knots: int, dt: float):
        self.block = block
        self.record = np.zeros(1, net_show_dtype(n_knots))
        self.every = max(1, int(1.0 / (NET_HZ * dt)))  # at least as often as a gateway sends (network.server.feed)
        self.tick: int | None = None  # the tick shown last
        self.asleep = False

    def publish(self, sim: NetSim, tick: int) -> None:
        """Show the net at `tick` if it is due (or went back: a restart); nothing while it sleeps on."""
        if self.tick is not None and sim.sleeping == self.asleep and (
                self.asleep or 0 <= tick - self.tick < self.every):
            return
        row = self.record[0]
        row["tick"], row["asleep"], row["pos"] = tick, sim.sleeping, sim.knot_pos
        self.block.publish(self.record, tick)
        self.tick, self.asleep = tick, sim.sleeping


def net_blocks(arena: Arena) -> list:
    return [arena[name] for name in NET_BLOCKS]


def newest_state(blocks, out: np.ndarray, at_most: int | None = None) -> bool:
    """Copy into out[0] the newest published net state whose tick is <= at_most (any if None).

    Returns False when no block holds such a state (a fresh run: the net is as built).
    """
    return _newest_block(blocks, out, at_most) is not None


def _newest_block(blocks, out: np.ndarray, at_most: int | None = None) -> int | None:
    """newest_state, returning the index of the block it copied from (None: none)."""
    best = None
    for i, block in enumerate(blocks):
        if block.version < 2:  # never published
            continue
        tick = block.tick
        if (at_most is None or tick <= at_most) and (best is None or tick > blocks[best].tick):
            best = i
    if best is not None:
        blocks[best].snapshot(out)
    return best


def _load(sim: NetSim, state) -> None:
    sim.load_state(state["pos"], state["vel"], bool(state["sleeping"]), int(state["quiet_ticks"]), int(state["tail"]))


def _step_granted(sim: NetSim, row: NetIO, control: Control, net_tick: int) -> int:
    """Step the free ticks granted (NetSim.step_free), a heartbeat every FREE_BEAT_TICKS; the tick reached."""
    while net_tick < row.granted:
        run = min(row.granted - net_tick, FREE_BEAT_TICKS)
        sim.step_free(run)
        net_tick += run
        control.beat(net_tick)
    return net_tick


def _write_state(sim: NetSim, tick: int, row) -> None:
    """The net's state at `tick` into a net_snapshot_dtype record (what _load takes back)."""
    row["tick"] = tick
    row["sleeping"] = sim.sleeping
    tail = sim.tail
    if tail is None:
        row["tail"] = -1
        row["quiet_ticks"] = sim.quiet_ticks
        sim.copy_state(row["pos"], row["vel"])
    else:  # the tail's start and its ticks: the state at `tick` follows from them alone
        row["tail"] = tail.ticks
        row["quiet_ticks"] = tail.quiet_ticks
        row["pos"] = tail.start_pos
        row["vel"] = tail.start_vel


def _publish(sim: NetSim, tick: int, state: np.ndarray, blocks, held: int, show: NetShow | None = None) -> int:
    """Publish the net's state at `tick` into the block other than `held`, the one holding the
    state it was stepped from (a run's state before and after it then sit in different blocks,
    and answering the same run again, which goes back to the state before it, overwrites only
    the state after it), and show it (NetShow, a run with a gateway); returns the block it
    published into."""
    _write_state(sim, tick, state[0])
    into = 1 - held
    blocks[into].publish(state, tick)
    if show is not None:
        show.publish(sim, tick)
    return into


def tail_until(sim: NetSim, net_tick: int) -> int:
    """-1, or the tick (physics ticks done) at which the linear tail holding `sim` at `net_tick` falls asleep."""
    return -1 if sim.tail is None else net_tick - sim.tail.ticks + sim.tail.sleep_at


def _answer(sim: NetSim, row: NetIO, ball: np.ndarray, radius: float, inv_mass: float, watch: np.ndarray) -> int:
    """Step a turn's run (NetSim.step_run) and write the answer into net_io; returns the ticks stepped."""
    taken, contact = sim.step_run(ball, radius, inv_mass, watch)
    row.taken = taken
    row.toi = contact.toi
    row.impulse[:] = contact.impulse
    row.offset[:] = contact.offset
    row.sleeping = int(sim.sleeping)
    row.box[:] = sim.box
    # An awake net's box for the ticks to come: the physics steps on without waiting while the
    # ball stays far from it (processes.workers.remote_net), and the free ticks check it.
    bound = sim.bound_box() if not sim.sleeping and sim.tail is None else None
    row.bounded = bound is not None
    if bound is not None:
        row.bound[:] = bound
    return taken


def _finish(control: Control, sim: NetSim, net_tick: int, busy: float, steps: int, timeline: Timeline | None) -> None:
    """The net's last words: its timeline, its work and its ticks, awake and in the tail."""
    if timeline is not None:
        timeline.save()
    control.finish(busy, 0.0, {"tick": net_tick, "busy_s": busy, "steps": steps, "awake_ticks": sim.awake_ticks,
                               "tail_ticks": sim.tail_ticks})


def _built(compiled: CompiledScene) -> tuple[NetSim, np.ndarray]:
    """The run's net, its kernels compiled before "ready" (nothing compiles mid-run), and the box
    engine.physics.world steps the ball tick by tick in (model.cloth_watch)."""
    compile_kernels(compiled.topology, compiled.dt)
    return compiled.net_sim(), compiled.model.cloth_watch


def net_worker(control: Control, arena: Arena, compiled: CompiledScene, options: RunOptions) -> None:
    """options: handles.net_baton (processes.runtime.handoff.Baton); faults (tests: end this process
    after publishing the state after the run that holds the crash tick and before saying it is
    done, the hardest moment, or after publishing a run of free ticks that holds it: a net in its
    linear tail, say; answer each run slow_turn_s later)."""
    topo = compiled.topology
    sim, watch = _built(compiled)
    if options.speculate:
        return _answer_queued_runs(control, arena, options, sim, watch)
    baton = options.handles.net_baton.attach(arena["net_baton"].array)
    faults = options.faults
    row = NetIO(arena["net_io"].array)
    blocks = net_blocks(arena)
    state = np.zeros(1, net_snapshot_dtype(topo.n_knots))
    ball = np.zeros(row.ball.shape)  # the turn's run, copied out of net_io: m, m/s
    held = _newest_block(blocks, state)  # the block holding the state the net is at
    if held is not None:
        _load(sim, state[0])  # restarted: resume from the newest state
        net_tick = int(state[0]["tick"])
    else:
        net_tick = 0
        held = _publish(sim, net_tick, state, blocks, 1)
    published = net_tick  # the tick of the newest published state
    show = NetShow(arena[NET_SHOW], topo.n_knots, compiled.dt) if NET_SHOW in arena.blocks else None
    if show is not None:
        show.publish(sim, net_tick)  # before "ready": a gateway shows the net from its first session on
    served = row.served
    answered = None  # the first tick of the run answered in net_io, once this incarnation has written one
    answered_end = None  # the tick after that run's last stepped tick
    control.start(net_tick)
    timeline = Timeline(options.timeline_dir, "net") if options.timeline_dir is not None else None
    busy = 0.0
    steps = 0
    try:
        while True:
            if timeline is not None:
                timeline.mark(IDLE)
            try:
                stop = baton.wait_turn(Control.HEARTBEAT_S, lambda: row.granted > net_tick) is None
            except HandoffTimeout:
                # A sleeping net: still alive, still listening; or restarted after the physics said
                # stop (the worker it replaces died stepping the last free ticks): finish them.
                stop = baton.stopped
                if not stop:
                    control.beat(net_tick)
                    continue
            t0 = time.perf_counter()
            if timeline is not None:
                timeline.mark(WORK)
            # First the free ticks granted so far (a nudge, or the ones before a ball tick).
            free_from = net_tick
            net_tick = _step_granted(sim, row, control, net_tick)
            steps += net_tick - free_from
            if published != net_tick:
                held = _publish(sim, net_tick, state, blocks, held, show)
                published = net_tick
            if faults is not None and faults.crashes_in(free_from, net_tick):
                faults.crash(faults.crash_at_tick)  # a free tick's turn: after publishing it
            if stop:
                busy += time.perf_counter() - t0
                break
            # `turn` is odd while the physics writes a turn's fields and even once they are all
            # written, and its give follows: a wake-up that finds it odd, or finds it changed
            # after the fields were read, is an earlier post (a nudge, a turn given again) and the
            # turn's own post comes later. x86-64 keeps both orders (stores are seen in program
            # order, loads are not passed by later loads).
            turn = row.turn
            if turn == served or turn % 2:  # a nudge, a turn already answered, or one being written
                busy += time.perf_counter() - t0
                continue
            tick = row.tick
            count = row.count
            ball[:count] = row.ball[:count]
            radius, inv_mass = row.radius, row.inv_mass
            if row.turn != turn:
                busy += time.perf_counter() - t0
                continue
            served = turn
            if net_tick > tick + count or (answered == tick and net_tick == answered_end):
                # A turn given again (the physics' wait ran out while we stepped it) for the run
                # answered last: net_io still holds that answer. Say so again, for a physics
                # that still waits for it; one that took it and went on skips it (Baton.done).
                # Past it (free ticks after it), the physics has taken it: nothing to answer.
                row.served = served
                if net_tick == answered_end:
                    baton.done(tick)
                busy += time.perf_counter() - t0
                continue
            if net_tick > tick:
                # The physics does this run again (it was restarted): back to the state before it.
                held = _newest_block(blocks, state, at_most=tick)
                _load(sim, state[0])
                net_tick = int(state[0]["tick"])
            if net_tick < tick:
                # Ticks the physics skipped because it knew the net asleep (it stays as it is) or in
                # its linear tail with the ball far from the tail's box (they count, as in NetSim.step).
                if sim.in_tail:
                    sim.step_free(tick - net_tick)
                elif not sim.sleeping:
                    raise RuntimeError(f"net worker: asked for tick {tick} at tick {net_tick} while awake; the "
                                       "ticks between were neither granted free nor given")
            taken = _answer(sim, row, ball[:count], radius, inv_mass, watch)
            net_tick = tick + taken
            answered, answered_end = tick, net_tick
            row.tail_until = tail_until(sim, net_tick)
            held = _publish(sim, net_tick, state, blocks, held, show)
            published = net_tick
            row.served = served
            steps += taken
            busy += time.perf_counter() - t0
            if faults is not None:
                faults.delay()
                if faults.crashes_in(tick, net_tick):
                    faults.crash(faults.crash_at_tick)
            baton.done(tick)
            control.beat(tick)
        _finish(control, sim, net_tick, busy, steps, timeline)
    finally:
        row.close()
        del blocks, show


def _answer_queued_runs(control: Control, arena: Arena, options: RunOptions, sim: NetSim, watch: np.ndarray) -> None:
    """The net worker of a speculating run (RunOptions.speculate; processes.workers.speculation):
    the runs come on a queue (`net_queue`, their data in the `net_runs` ring) and the ticks
    between them as a grant (`net_spec`); it steps the granted ticks up to the next run's first,
    the run (NetSim.step_run), answers it into `net_answers` and goes on, the physics meanwhile
    stepping past its runs as if the net touched none. At a touch it halts, the tick after the
    touch being the physics' to step again, until the physics has gone back (its epoch moves):
    the runs and grants after the touch were the physics' guesses, and it gives them again.

    Restarts: the net's state after each run goes into the run's slot of `net_states` before the
    run is counted answered. A restarted net worker goes on from its state after the last run
    answered (halted there if that run touched and the physics has not gone back since) and
    steps the grants again; the free ticks between runs are stepped as they were. A restarted
    physics worker resumes at a snapshot with some runs posted before it (processes.workers.cut),
    takes back the runs posted after the last of them (TurnQueue.withdraw: no net, restarted or
    not, takes one of them again) and asks the net back to its state after it (SPEC_BACK): the
    net goes there, counts that run the last answered, and halts until the physics moves the
    epoch."""
    queue = options.handles.net_queue.attach(arena["net_queue"].array)
    runs, answers, states = arena["net_runs"].array, arena["net_answers"].array, arena["net_states"].array
    words = memoryview(arena["net_spec"].array.view("<i8")).cast("B").cast("q")
    faults = options.faults
    ball = np.zeros(runs["ball"].shape[1:])
    built = np.zeros(1, states.dtype["state"])
    _write_state(sim, 0, built[0])  # the net as built: the state after "run 0"
    done = queue.answered
    net_tick, touched, answered_in = _go_back(sim, states, built, done)
    epoch = words[SPEC_EPOCH]  # moves only while the net is halted: at a touch, or asked back
    halted = touched and epoch == answered_in  # a restart at a touch the physics has not gone back from
    steps = 0
    busy = 0.0
    timeline = Timeline(options.timeline_dir, "net") if options.timeline_dir is not None else None
    control.start(net_tick)

    def pending() -> bool:
        if words[SPEC_BACK] >= 0:
            return True
        return words[SPEC_EPOCH] != epoch if halted else words[SPEC_GRANTED] > net_tick

    try:
        while True:
            back = words[SPEC_BACK]
            if back >= 0:  # a restarted physics: back to the state after run `back`, halted there
                net_tick, _, _ = _go_back(sim, states, built, back)
                done, epoch, halted = back, words[SPEC_EPOCH], True
                queue.answer(done)  # killed after this, a restarted net goes back again
                words[SPEC_BACK] = -1
                queue.wake_hub()  # last: the physics waits for the count and the word both
                continue
            if halted and words[SPEC_EPOCH] != epoch:
                epoch, halted = words[SPEC_EPOCH], False  # the physics went back: its new runs follow
            granted = words[SPEC_GRANTED]  # before the queue's count: a grant past a run follows its post
            posted = queue.posted
            run = runs[(done + 1) % SPEC_RUNS] if posted > done and not halted else None
            target = granted if run is None else min(granted, int(run["tick"]))
            if not halted and (net_tick < target or run is not None and net_tick == int(run["tick"])):
                t0 = time.perf_counter()
                if timeline is not None:
                    timeline.mark(WORK)
                while net_tick < target:
                    ticks = min(target - net_tick, FREE_BEAT_TICKS)
                    sim.step_free(ticks)
                    net_tick += ticks
                    steps += ticks
                    control.beat(net_tick)
                if run is not None and net_tick == int(run["tick"]):
                    count = int(run["count"])
                    ball[:count] = run["ball"][:count]
                    taken, contact = sim.step_run(ball[:count], float(run["radius"]), float(run["inv_mass"]), watch)
                    net_tick += taken
                    steps += taken
                    done += 1
                    halted = contact.toi != NO_CONTACT
                    slot = states[done % NET_STATES]
                    slot["run"] = -1  # torn until its number is written, last
                    _write_state(sim, net_tick, slot["state"])
                    slot["epoch"], slot["touched"], slot["run"] = epoch, halted, done
                    if faults is not None:
                        faults.delay()  # a slow net (tests): the physics speculates further
                    _write_answer(answers[done % SPEC_RUNS], sim, done, taken, contact, net_tick)
                    if faults is not None and faults.crashes_in(-1, net_tick):
                        faults.crash(net_tick)  # the first run past the crash tick, answered but not counted
                    queue.answer(done)
                    control.beat(net_tick)
                busy += time.perf_counter() - t0
                continue
            if queue.stopped and (halted or posted <= done and granted <= net_tick):
                break
            if timeline is not None:
                timeline.mark(IDLE)
            if not queue.wait_work(done if not halted else queue.posted, Control.HEARTBEAT_S, pending):
                control.beat(net_tick)  # nothing to do: still alive, still listening
        _finish(control, sim, net_tick, busy, steps, timeline)
    finally:
        words.release()
        del runs, answers, states


def _go_back(sim: NetSim, states: np.ndarray, built: np.ndarray, run: int) -> tuple[int, bool, int]:
    """Load the net's state after run `run` (0: as built) from `net_states`; returns its tick,
    whether the net touched the ball in that run and the epoch it was answered in."""
    if run == 0:
        _load(sim, built[0])
        return 0, False, 0
    slot = states[run % NET_STATES]
    if int(slot["run"]) != run:
        raise RuntimeError(f"net worker: the state after run {run} is no longer kept (its slot holds run "
                           f"{int(slot['run'])}; net_states keeps {NET_STATES})")
    _load(sim, slot["state"])
    return int(slot["state"]["tick"]), bool(slot["touched"]), int(slot["epoch"])


def _write_answer(answer, sim: NetSim, run: int, taken: int, contact, net_tick: int) -> None:
    """A queued run's answer (SPEC_ANSWER_DTYPE) from NetSim.step_run's, its number written last."""
    answer["taken"] = taken
    answer["toi"] = contact.toi
    answer["impulse"] = contact.impulse
    answer["offset"] = contact.offset
    answer["sleeping"] = sim.sleeping
    answer["tail_until"] = tail_until(sim, net_tick)
    answer["box"] = sim.box
    bound = sim.bound_box() if not sim.sleeping and sim.tail is None else None
    answer["bounded"] = bound is not None
    if bound is not None:
        answer["bound"] = bound
    answer["run"] = run
