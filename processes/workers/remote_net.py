"""The physics worker's stand-in for engine.physics.world's NetSim (RemoteNet): the net stepped by the net
worker, handed its turn through shared memory, so the physics steps the same bits as in-process."""
from __future__ import annotations

import time

import numpy as np

from net_kernel import NO_CONTACT, NetContact, NetSim
from net_kernel.sim import ball_far_from_box
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.runtime.timeline import WAIT_NET, WORK, Timeline
from processes.workers.layout import NetIO
from processes.workers.options import RunOptions

# A hand-off waits options.handoff_s, gives the turn again (a killed net worker is being
# restarted) and waits again, for this long in all.
NET_GIVE_UP_S = 60.0
# Ticks between two wake-ups of a net worker whose net rings in its linear tail: 16 ms at the
# match's 1 kHz, the period of a 60 Hz net message.
TAIL_NUDGE_TICKS = 16


class KnownNet:
    """What the physics worker knows of the net worker's net from its answers: asleep, the tick
    its linear tail falls asleep, the box its knots froze or ring in, and the box its energy
    bounds an awake net's knots to. Nothing known yet (a fresh run's net is as built and awake; a
    resumed one, whatever the net says at its first answer): awake is the guess that can cost a
    hand-off but no bit. The stand-ins for NetSim (RemoteNet, speculation.SpeculativeNet) build
    on it.

    Args:
        world: the physics state's world record (its tick says which tick is being stepped).
        local: a NetSim of the same net as built (its knot radius, tick and built shape).
    """

    def __init__(self, world, local: NetSim):
        self.world = world
        self.local = local
        self._sleeping = False
        self._tail_until = -1  # the tick at which the tail of the last answer falls asleep (-1: no tail)
        self.box = local.box.copy()
        self._bounded = False  # whether `bound` holds the awake net's knots (the net's last answer)
        self.bound = np.zeros((2, 3))

    @property
    def sleeping(self) -> bool:
        """Asleep after the ticks done, as far as the net's last answer tells."""
        return self._sleeping or 0 <= self._tail_until <= int(self.world["tick"])

    @property
    def in_tail(self) -> bool:
        """In its linear tail after the ticks done, as far as the net's last answer tells."""
        return self._tail_until > int(self.world["tick"])

    def learn(self, sleeping, tail_until, box, bounded, bound) -> None:
        """The net as an answer says it is after its run."""
        self._sleeping = bool(sleeping)
        self._tail_until = int(tail_until)
        self.box[:] = box
        self._bounded = bool(bounded)
        if self._bounded:
            self.bound[:] = bound

    def far_ticks(self, ball: np.ndarray, first: int, ball_radius: float) -> int:
        """How many of a run's first ticks (ball[j]: the ball at tick first + j's start) the ball
        cannot touch the net in, as far as what is known tells: a sleeping net or one ringing in
        its tail and the ball far from the box it froze or rings in (NetSim.step leaves it or only
        counts the tick), an awake net and the ball far from its bound (NetSim.step takes the tick
        free: the knots' own box lies inside)."""
        local = self.local
        j = 0
        while j < len(ball):
            tick = first + j
            if self._sleeping or self._tail_until > tick or 0 <= self._tail_until <= tick:
                if not ball_far_from_box(self.box, True, local.knot_radius, local.dt, ball[j, 0], ball[j, 1],
                                         ball_radius):
                    break
            elif not (self._bounded and ball_far_from_box(self.bound, False, local.knot_radius, local.dt, ball[j, 0],
                                                          ball[j, 1], ball_radius)):
                break
            j += 1
        return j


class RemoteNet(KnownNet):
    """The physics worker's stand-in for the NetSim in engine.physics.world: same `sleeping`, `in_tail`,
    step_run() and step_free().

    Args:
        control: the physics worker's Control (heartbeats while it waits).
        arena, options: the run's (net_io, net_baton).
        world: the physics state's world record (its tick says which tick is being stepped).
        local: a NetSim of the same net as built (its knot radius, tick and built shape).

    A sleeping net and a ball that cannot touch its frozen shape cost no hand-off, exactly as
    NetSim.step returns early: the stand-in keeps the box the net froze in (from net_io after each
    ball tick). So does a net in its linear tail (net_kernel/tail.py) and a ball far from the box
    that holds the tail's knots: NetSim.step only counts such a tick, so the stand-in grants it
    free, and knows from the net's last answer the tick at which the tail falls asleep. So does
    an awake net and a ball far from the box its energy bounds the knots to until the ball next
    comes near (NetSim.bound_box, from the net's last answer): NetSim.step takes such a tick
    free (the knots' own box lies inside), so the stand-in grants it and the net worker steps
    it on the other core, checking the bound. What it
    knows of `sleeping` otherwise comes from the net's last answer, so after free ticks, in which
    the net may have fallen asleep or into its tail, it may still think the net awake: that costs
    a hand-off more, never a different bit (the net worker then steps exactly as NetSim.step would).
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, world, local: NetSim):
        super().__init__(world, local)
        self.control = control
        self.timeline: Timeline | None = None  # the physics' (its waits for the net are marked), or None
        self.baton = options.handles.net_baton.attach(arena["net_baton"].array)
        self.handoff_s = options.handoff_s
        self.io = NetIO(arena["net_io"].array)
        self._none = np.zeros(3)
        self.waits = 0.0
        self.ball_ticks = 0  # ticks handed to the net worker with the ball (and waited for)
        self.runs = 0  # hand-offs of those ticks (a run of them each)
        self.free_ticks = 0  # ticks granted without the ball (not waited for)
        self.turns_again = 0  # turns given again because the net's answer took longer than one wait's bound
        self._nudged = -TAIL_NUDGE_TICKS  # the tick of the last wake-up for free ticks

    def step_free(self, ticks: int) -> None:
        """NetSim.step_free: grant the net the ticks just done (the world's tick is past them) and go on."""
        if ticks > 0:
            tick = int(self.world["tick"])
            self.io.granted = tick
            self.free_ticks += ticks
            # A sleeping net has nothing to step: the net worker takes the grant at its next turn. A
            # tail's ticks only count: the worker is woken TAIL_NUDGE_TICKS apart, so what it
            # publishes (a gateway's net messages read it) stays that close behind, and once more
            # after the tail fell asleep, so that it shows the net asleep.
            if self._sleeping or (self.in_tail and tick - self._nudged < TAIL_NUDGE_TICKS):
                return
            if self.sleeping and self._nudged >= self._tail_until:
                return
            self._nudged = tick
            self.baton.nudge()

    def step_run(self, ball: np.ndarray, ball_radius: float, ball_inv_mass: float,
                 free_outside: np.ndarray) -> tuple[int, NetContact]:
        """NetSim.step_run, done by the net worker in one hand-off (called after the run's ball
        ticks, as engine.physics.world does). Its first ticks cost no hand-off while the net's last answer
        says it sleeps or rings in its tail and the ball is far from the box it froze or rings in:
        NetSim.step leaves such a net untouched or only counts the tick."""
        count = len(ball)
        first = int(self.world["tick"]) - count
        j = self.far_ticks(ball, first, ball_radius)
        # The ticks of the tail, or of an awake net far from its bound, among them: stepped free
        # (NetSim.step with the ball far from the knots' own box, which lies inside, does so
        # too); a sleeping net's (from the tick its tail falls asleep on) wait for its next turn.
        awake_to = first if self._sleeping else first + j if self._tail_until < 0 else min(first + j, self._tail_until)
        granted = awake_to > first
        if granted:
            self.io.granted = awake_to
            self.free_ticks += awake_to - first
        if granted and not self.in_tail:
            self.baton.nudge()  # an awake net's ticks: the net worker steps them on the other core
        if j == count:
            self._none[:] = 0.0
            return count, NetContact(NO_CONTACT, self._none, self._none)
        started = time.perf_counter()
        row = self.io
        # `turn` odd while the fields are written, even once they all are (see net_worker): the
        # worker may wake on an earlier post at any moment and must never read half of them.
        row.turn = row.turn // 2 * 2 + 1
        tick = first + j
        row.tick = tick
        row.count = count - j
        row.ball[:count - j] = ball[j:]
        row.radius = ball_radius
        row.inv_mass = ball_inv_mass
        row.turn += 1
        self.baton.give(tick)
        if self.timeline is not None:
            self.timeline.mark(WAIT_NET)
        # The net may still be stepping free ticks, or restarting: stay alive and ask again (a
        # new turn; net_io still holds the run).
        self.baton.wait_done_or_retry(tick, self.handoff_s, NET_GIVE_UP_S, self._ask_again)
        if self.timeline is not None:
            self.timeline.mark(WORK)
        self.learn(row.sleeping, row.tail_until, row.box, row.bounded, row.bound)
        self.waits += time.perf_counter() - started
        self.ball_ticks += row.taken
        self.runs += 1
        return j + row.taken, NetContact(row.toi, row.impulse.copy(), row.offset.copy())

    def _ask_again(self, tick: int) -> None:
        self.control.beat(tick)
        self.turns_again += 1
        self.io.turn += 2  # the same fields, a new turn (even: nothing is being written)
