"""The watch task: N spectators and M players that take every message, and know when they could not.

Players send a zero force at input_hz (an arm at rest). Per snapshot the receipt time
(CLOCK_MONOTONIC) and tick go to the spec's record (.npz) for the latency; per client the snapshots,
the messages missed (gaps in the sequence numbers, swarm.tally), tick and score regressions,
goodbyes. A spectator subscribes to the feed its welcome names (its snapshots and events come
there, heartbeats and goodbye on the session). With "rejoin" a client silent for silence_s, or
told goodbye unknown_session, says hello again (a restarted gateway lost its sessions).

The receive loop waits on the sockets' ZMQ_FD descriptors with epoll, which costs per ready
socket, not per socket (zmq_poll over 500 sockets costs a few hundred microseconds a call), and
drains each socket without blocking, up to DRAIN_BATCH messages a visit. One spectator in
the spec's timed_every (and every player and session) is timed: read as soon as its socket signals, its
snapshots' receipt times recorded for the latency. The other spectators' feeds are read in bulk
every bulk_period_s, a few snapshots a visit: each visit of a socket costs libzmq a wake-up and a
probe of the empty queue however many messages wait, so the bulk pays it once for several
(their counts and gaps are exact; their rates are timed to within the period). A snapshot or a
heartbeat is counted from its header alone (swarm.tally); one in validate_every of them is
decoded in full, and so is every other message.

The swarm measures itself from ready to the end of its receive loop: its own CPU (every thread,
libzmq's included) per message received; how busy the loop was (the share of wall time not spent
waiting in epoll); its demand, the largest share of wall time one of its threads (the loop's, or
a libzmq I/O thread's) was on a CPU or runnable and waiting for one (schedstat), which a machine
shared with other work cannot hide; the backlog, messages found queued on a timed socket at one
visit (at 120 Hz a loop that keeps up finds one); how late the bulk reads started; the longest
turn of the loop. A swarm with a demand of DEMAND_SATURATED_PCT or more, or whose bulk reads
started a whole period late half the time (under half their cadence), was behind: the rates it
measured are its own limit, not the server's.
"""
from __future__ import annotations

import os
import select
import time
from array import array
from collections import Counter

import numpy as np
import zmq

from processes.network.client.client import Client, Rejected
from processes.network.wire import NO_TOKEN, GoodbyeReason, Kind, RejectReason
from processes.stress.probes import cpu_seconds, fd_count, rss_kb, thread_cpu_seconds, thread_sched_seconds
from processes.stress.swarm import context, emit
from processes.stress.swarm.spec import WatchSpec
from processes.stress.swarm.tally import Sequence, Tally, header

# A watch swarm's spectators read their feeds on libzmq I/O thread 1, the sessions stay on 0: with
# one thread, 250 feeds' 30,000 messages a second delayed the heartbeats out (as in the gateway).
FEED_OPTIONS = {zmq.AFFINITY: 1 << 1}
DRAIN_BATCH = 64  # messages read from one socket at one visit; the rest wait for the next turn
DEMAND_SATURATED_PCT = 50.0  # runnable more than half the time: behind more often than not
SNAPSHOT = Kind.SNAPSHOT
SWEEP_PERIOD_S = 0.1  # heartbeats, inputs, rejoins and the end are seen to this often
BACKLOG_BINS = 257  # backlog histogram: 0..255 messages, the last bin for more


class _Watcher:
    def __init__(self, client: Client, role: str):
        self.client = client
        self.role = role
        self.welcomed = False
        self.tally = Tally()
        self.session = Sequence()
        self.feed = None  # the client's feed socket as registered with epoll
        self.timed = False  # read on every signal (its latency is recorded), else in bulk
        self.feed_fd = -1
        self.session_fd = -1
        self.feed_seq = Sequence()
        self.last = 0.0  # last message of any kind
        self.last_score = (-1, -1)
        self.goodbye: str | None = None
        self.hello_at = 0.0
        self.hellos = 0
        self.rejoined = 0
        self.next_input = 0.0
        self.inputs = 0


def _percentile(hist: np.ndarray, q: float) -> int:
    """The q-th percentile of a histogram of small integers (bin i holds the count of value i)."""
    total = int(hist.sum())
    if not total:
        return 0
    return int(np.searchsorted(np.cumsum(hist), q / 100.0 * total))


def _pin(spec: WatchSpec) -> set[int]:
    """Pin this process to the CPU the spec names (every thread started after this inherits it):
    a swarm kept off the server's cores, or starved on purpose. The CPUs it had before."""
    allowed = os.sched_getaffinity(0)
    if spec.pin_cpu is not None:
        os.sched_setaffinity(0, {spec.pin_cpu})
    return allowed


def _unpin(allowed: set[int]) -> None:
    """Give every thread of this process (libzmq's too) the CPUs it had before _pin: leaving,
    closing and the report are not measured, and a swarm starved on purpose on its pinned CPU
    would take minutes over them."""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), allowed)
        except ProcessLookupError:  # a thread that ended since the listing
            pass


def _lower_priority(spec: WatchSpec) -> None:
    """Lower this process's priority by the spec's nice, once its clients are in (they join at full
    speed): for the calling thread and for the session's autogroup, which holds every thread of
    the swarm (a session of its own); with autogroup scheduling (sched(7)) a nice value only
    weighs tasks of one session against each other."""
    if spec.nice:
        os.nice(spec.nice)
        try:
            with open("/proc/self/autogroup", "w") as f:
                f.write(str(spec.nice))
        except OSError:  # no autogroup scheduling here: the thread's nice value is what there is
            pass


def watch(spec: WatchSpec) -> dict:
    """Run the watch task `spec` describes: join, receive until the end, leave; its report."""
    return Watch(spec).run()


class Watch:
    """One watch swarm's clients, its epoll loop and what it measures of them and of itself.

    Phases: the clients join (__init__ builds them, run() says hello), the loop turns (poll, drain
    the signalled sockets, read the bulk feeds, sweep: heartbeats, inputs, rejoins, the ready
    mark), then stop (leave, close) and report.
    """

    def __init__(self, spec: WatchSpec):
        self.allowed_cpus = _pin(spec)
        self.spec = spec
        self.fds_before = fd_count()
        # a spectator has two sockets: its session and its feed
        self.zctx = context(2 * spec.spectators + spec.players, io_threads=2)
        self.watchers = [_Watcher(Client(spec.address, "spectator", f"{spec.name}{i}", zctx=self.zctx,
                                         feed_options=FEED_OPTIONS), "spectator") for i in range(spec.spectators)]
        self.watchers += [_Watcher(Client(spec.address, "player", f"{spec.name}p{i}", zctx=self.zctx), "player")
                          for i in range(spec.players)]
        for i, w in enumerate(self.watchers):
            w.timed = w.role == "player" or i % spec.timed_every == 0
        self.epoll = select.epoll()
        self.entries: dict[int, tuple] = {}  # ZMQ_FD -> (watcher, socket, on_feed), every socket
        self.bulk: dict[int, tuple] = {}  # the feeds read every bulk_period_s
        self.ready: dict[int, tuple] = {}  # sockets to drain this turn: signalled, or left with messages last turn
        for w in self.watchers:
            w.session_fd = self.register(w, w.client.sock, False)
        self.rejected: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()
        self.kinds: Counter[str] = Counter()
        self.ticks, self.times = array("q"), array("d")  # the timed snapshots' ticks and receipt times
        self.score_regressions = 0
        self.events = 0
        self.received = 0  # messages read since ready
        self.sample_in = spec.validate_every  # header-only messages until the next one decoded in full
        self.input_dt = 1.0 / spec.input_hz
        self.done: set[_Watcher] = set()  # rejected for good
        self.all_finished = False
        self.ready_at = 0.0  # when every client was in (or the join deadline passed): the measured window starts
        self.started = self.end = self.join_deadline = 0.0
        self.rss_start = None
        self.next_sweep = self.next_bulk = self.last_sweep = 0.0
        self.sweep_gap = 0.0
        self.bulk_lags = array("d")
        self.waited = 0.0  # s spent waiting in epoll since ready
        self.turn_max = 0.0
        self.cpu_at_ready = 0.0
        self.threads_at_ready: dict[str, float] = {}
        self.sched_at_ready: dict[str, tuple[float, float]] = {}
        self.backlog = np.zeros(BACKLOG_BINS, np.int64)

    def register(self, w: _Watcher, sock, on_feed: bool) -> int:
        """Watch one of w's sockets: a timed one (or a session) on epoll, a bulk feed on the period."""
        fd = sock.get(zmq.FD)
        self.entries[fd] = (w, sock, on_feed)
        if on_feed and not w.timed:
            self.bulk[fd] = self.entries[fd]
        else:
            self.ready[fd] = self.entries[fd]  # drained once now: what came before signalled nobody
            self.epoll.register(fd, select.EPOLLIN)
        return fd

    def unregister(self, fd: int) -> None:
        self.entries.pop(fd, None)
        self.ready.pop(fd, None)
        if self.bulk.pop(fd, None) is None:
            try:
                self.epoll.unregister(fd)
            except (OSError, ValueError):  # closed already: epoll forgot it with the descriptor
                pass

    def finished(self, w: _Watcher) -> bool:
        return w.goodbye is not None or w in self.done

    def run(self) -> dict:
        """Join, turn the loop until the end (or every goodbye), leave; the report."""
        spec = self.spec
        self.join_deadline = time.monotonic() + spec.join_timeout
        for w in self.watchers:
            w.client.hello()
            w.hello_at = time.monotonic()
            w.hellos = 1
        self.started = time.monotonic()
        self.end = self.started + spec.duration
        while True:
            now = self.turn()
            if now >= self.end or (spec.until_goodbye and self.ready_at and self.all_finished):
                break
        return self.stop()

    def turn(self) -> float:
        """One turn of the loop: wait for a signal (or the next bulk read), drain what is ready,
        the bulk feeds when due, the sweep when due; the time at its end."""
        monotonic, ready = time.monotonic, self.ready
        before = monotonic()
        events_ready = self.epoll.poll(0 if ready else min(0.02, max(0.0, self.next_bulk - before)))
        now = monotonic()
        if self.ready_at:
            self.waited += now - before
        entries = self.entries
        for fd, _ in events_ready:
            entry = entries.get(fd)
            if entry is not None:
                ready[fd] = entry
        batch = list(ready.items())
        ready.clear()
        for fd, entry in batch:
            if entries.get(fd) is None:
                continue  # unregistered by a message earlier in this turn (a welcome's new feed)
            n = self.drain(fd, *entry)
            if n == DRAIN_BATCH:
                ready[fd] = entry  # more may wait: its descriptor will not signal them again
            if self.ready_at:
                self.backlog[min(n, BACKLOG_BINS - 1)] += 1
        now = monotonic()
        if now >= self.next_bulk:
            if self.ready_at and self.next_bulk:
                self.bulk_lags.append(now - self.next_bulk)  # how late the bulk read started: the loop's lag
            self.next_bulk = now + self.spec.bulk_period_s
            bulk = self.bulk
            for fd, entry in list(bulk.items()):
                if fd in bulk:
                    self.drain(fd, *entry)
        turn = monotonic() - now
        now += turn
        if self.ready_at:
            self.turn_max = max(self.turn_max, turn)
        if now >= self.next_sweep:
            self.sweep(now)
        return now

    def drain(self, fd: int, w: _Watcher, sock, on_feed: bool) -> int:
        """Read what waits on one socket, up to DRAIN_BATCH messages; how many were read.

        Snapshots and heartbeats are counted from their fixed header (one in validate_every
        decoded in full); every other message is decoded (_decoded)."""
        client = w.client
        t = time.monotonic()
        timed = w.timed
        heartbeats = 0
        sample_in = self.sample_in
        recv_flags, again = zmq.NOBLOCK, zmq.Again
        n = 0
        while n < DRAIN_BATCH:
            try:
                data = sock.recv(recv_flags)
            except again:
                break
            n += 1
            fixed = header(data)
            if fixed is None:
                self._decoded(w, data, on_feed, t)
                continue
            kind, seq, tick = fixed
            if kind == SNAPSHOT:
                w.tally.snapshot(tick, t)
                if timed:
                    self.ticks.append(tick)
                    self.times.append(t)
                if tick > client.tick:
                    client.tick = tick
            elif on_feed:
                self.bad["not_on_feed"] += 1  # only snapshots and events go out on the feed
                continue
            else:
                heartbeats += 1
            if on_feed:
                w.feed_seq.see(seq)
            else:
                w.last = t  # the session's liveness (a restarted gateway's feed is another socket)
                if w.welcomed:
                    w.session.see(seq)
            sample_in -= 1
            if sample_in == 0:  # a sample of the process's snapshots and heartbeats, decoded in full
                sample_in = self.spec.validate_every
                self._sample(w, data, kind)
        self.sample_in = sample_in
        if heartbeats:
            self.kinds["heartbeat"] += heartbeats
        if self.ready_at:
            self.received += n
        return n

    def _sample(self, w: _Watcher, data: bytes, kind: int) -> None:
        """A snapshot or heartbeat counted from its header, decoded in full: valid, the score never back."""
        message = w.client.drops.decode(data)
        if message is None:
            self.bad[Kind(kind).name.lower()] += 1
        elif kind == SNAPSHOT:
            score = (int(message["games_won"].sum()), int(message["score"].sum()))
            self.score_regressions += score < w.last_score
            w.last_score = score

    def _decoded(self, w: _Watcher, data: bytes, on_feed: bool, t: float) -> None:
        """A message without a fixed header (welcome, reject, goodbye, event, net), decoded and acted on."""
        message = w.client.drops.decode(data)
        if message is None:
            self.bad["other"] += 1
            return
        seq = message.seq
        self.kinds[message.kind.name.lower()] += 1
        if on_feed:
            if message.kind not in (Kind.EVENT, Kind.NET):
                self.bad["not_on_feed"] += 1  # only snapshots, events and a cloth net's knots go out on the feed
                return
            w.feed_seq.see(seq)
            self.events += message.kind == Kind.EVENT
            return
        if message.kind in (Kind.WELCOME, Kind.REJECT):
            self._answered(w, message, t)
            return
        if message.kind == Kind.GOODBYE:
            if message["reason"] == GoodbyeReason.UNKNOWN_SESSION and self.spec.rejoin:
                w.client.hello()  # a restarted gateway lost our session: hello again now
                w.hello_at = t
                w.hellos += 1
            else:
                w.goodbye = message["reason"].name.lower()
        elif message.kind == Kind.EVENT:
            self.events += 1
        if w.welcomed:
            w.session.see(seq)
        w.last = t

    def _answered(self, w: _Watcher, message, t: float) -> None:
        """A welcome or a reject on w's session: its feed (re)registered, a rejection counted."""
        client = w.client
        if w.feed is not None:  # a welcome may name a new feed: the old socket may close now
            self.unregister(w.feed_fd)
        try:
            client.accept(message)
        except Rejected as err:
            self.rejected[err.reason.name.lower()] += 1
            if err.reason == RejectReason.BAD_TOKEN:
                client.token = NO_TOKEN  # a restarted gateway forgot it: ask for any seat
            elif not self.spec.rejoin:
                self.done.add(w)
            if w.feed is not None and client.feed is w.feed:
                w.feed_fd = self.register(w, w.feed, True)
            return
        w.rejoined += w.welcomed
        w.welcomed = True
        w.session.last = message.seq
        w.last = t
        if client.feed is not w.feed:  # subscribed (or, after a restart, to a new port)
            w.feed_seq.last = 0
        w.feed = client.feed
        if w.feed is not None:
            w.feed_fd = self.register(w, w.feed, True)

    def sweep(self, now: float) -> None:
        """Every SWEEP_PERIOD_S: the ready mark once every client is in, then each client's
        heartbeat, a player's input, a silent client's hello."""
        spec = self.spec
        if self.ready_at and self.last_sweep:
            self.sweep_gap = max(self.sweep_gap, now - self.last_sweep)  # our own stalls: a heartbeat may be late by this
        self.last_sweep = now
        self.next_sweep = now + SWEEP_PERIOD_S
        self.all_finished = all(self.finished(w) for w in self.watchers)
        if not self.ready_at and (all(w.welcomed or self.finished(w) for w in self.watchers)
                                  or now > self.join_deadline):
            self.mark_ready(now)
        for w in self.watchers:
            if self.finished(w):
                continue
            client = w.client
            sent = client.seq
            if w.welcomed:
                client.heartbeat_if_due()
                if w.role == "player" and now >= w.next_input:
                    w.next_input = now + self.input_dt
                    client.send_input(np.zeros(6))
                    w.inputs += 1
            if spec.rejoin and now - max(w.last, w.hello_at) > spec.silence_s and w.hellos < 100:
                client.hello()  # the gateway went silent: a restarted one needs a hello
                w.hello_at = now
                w.hellos += 1
            if client.seq != sent:  # a send may take the socket's read signal with it (zmq_getsockopt
                self.ready[w.session_fd] = self.entries[w.session_fd]  # ZMQ_FD): drain it next turn all the same

    def mark_ready(self, now: float) -> None:
        """The measured window starts: the process's memory, CPU and threads' schedule noted, the
        priority lowered, {"event": "ready"} told."""
        self.ready_at = now
        self.rss_start = rss_kb()
        self.cpu_at_ready = cpu_seconds()
        self.threads_at_ready = thread_cpu_seconds("self")
        self.sched_at_ready = thread_sched_seconds()
        _lower_priority(self.spec)
        self._emit_ready(now)

    def _emit_ready(self, t: float) -> None:
        emit({"event": "ready", "welcomed": sum(w.welcomed for w in self.watchers), "rejected": dict(self.rejected),
              "fds": fd_count(), "t": t})

    def stop(self) -> dict:
        """The measured window ends: the clients leave and close, the record is written; the report."""
        stopped = time.monotonic()
        cpu_window = (cpu_seconds() or 0.0) - self.cpu_at_ready
        threads = {name: round(c - self.threads_at_ready.get(name, 0.0), 3)
                   for name, c in thread_cpu_seconds("self").items()}
        sched_at_stop = thread_sched_seconds()
        if not self.ready_at:
            self.ready_at = stopped
            self._emit_ready(stopped)
        if self.spec.pin_cpu is not None:
            _unpin(self.allowed_cpus)
        if self.spec.leave_at_end:
            for w in self.watchers:
                if w.goodbye is None and w.welcomed:
                    w.client.sock.setsockopt(zmq.LINGER, 1000)  # the goodbye leaves before the socket goes
                    w.client.leave()
        rss_end = rss_kb()
        self.epoll.close()
        for w in self.watchers:
            w.client.close()
        self.zctx.term()
        fds_after = fd_count()
        if self.spec.record:
            np.savez(self.spec.record, ticks=np.frombuffer(self.ticks, np.int64),
                     times=np.frombuffer(self.times, np.float64))
        return self.report(stopped, cpu_window, threads, sched_at_stop, rss_end, fds_after)

    def report(self, stopped: float, cpu_window: float, threads: dict, sched_at_stop: dict, rss_end, fds_after) -> dict:
        """What the clients saw (counts, gaps, regressions, rates) and the swarm's own load."""
        watchers = self.watchers
        welcome = next((w.client.welcome for w in watchers if w.client.welcome is not None), None)
        rates = [r for r in (w.tally.rate_hz() for w in watchers) if r is not None]
        return {"clients": len(watchers), "timed": sum(w.timed for w in watchers),
                "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(self.rejected),
                "snapshots": sum(w.tally.snapshots for w in watchers), "missed": sum(w.session.missed for w in watchers),
                "missed_max": max((w.session.missed for w in watchers), default=0),
                "feed_missed": sum(w.feed_seq.missed for w in watchers),
                "feed_missed_max": max((w.feed_seq.missed for w in watchers), default=0),
                "on_feed": sum(w.feed is not None for w in watchers),
                "seq_resets": sum(w.session.resets for w in watchers), "rejoined": sum(w.rejoined for w in watchers),
                "hellos": sum(w.hellos for w in watchers), "inputs": sum(w.inputs for w in watchers),
                "goodbyes": dict(Counter(w.goodbye for w in watchers if w.goodbye)),
                "no_goodbye": sum(1 for w in watchers if w.goodbye is None and w.welcomed),
                "events": self.events, "messages": dict(self.kinds), "invalid": dict(self.bad),
                "decode_drops": {k: v for w in watchers for k, v in w.client.drops.by_reason.items()},
                "regressions": {"score": self.score_regressions,
                                "tick": sum(w.tally.tick_regressions for w in watchers)},
                "rate_min": min(rates, default=0.0), "rate_median": float(np.median(rates)) if rates else 0.0,
                "rate_max": max(rates, default=0.0),
                "dt": float(welcome["dt"]) if welcome is not None else None,
                "seconds": stopped - self.started, "fds_before": self.fds_before, "fds_after": fds_after,
                "rss_start_kb": self.rss_start or rss_end, "rss_end_kb": rss_end,
                "last_tick": max((w.tally.last_tick for w in watchers), default=-1),
                "sweep_gap_max_s": round(self.sweep_gap, 3),
                "load": self.load(stopped, cpu_window, threads, sched_at_stop)}

    def load(self, stopped: float, cpu_window: float, threads: dict, sched_at_stop: dict) -> dict:
        """The swarm's own load over the measured window: CPU, busy share, demand, backlog, lags."""
        ready_at = self.ready_at
        window = max(stopped - ready_at, 1e-9)
        busy_pct = round(100.0 * (1.0 - self.waited / window), 1) if stopped > ready_at else None
        lags_ms = 1000.0 * np.frombuffer(self.bulk_lags, np.float64) if len(self.bulk_lags) else np.zeros(1)
        lag_p50_ms = float(np.percentile(lags_ms, 50))
        demand = {}  # per thread: % of the window on a CPU or runnable and waiting for one, and waiting
        for name, (on_cpu, waiting) in sched_at_stop.items():
            on0, wait0 = self.sched_at_ready.get(name, (0.0, 0.0))
            demand[name] = (round(100.0 * (on_cpu - on0 + waiting - wait0) / window, 1),
                            round(100.0 * (waiting - wait0) / window, 1))
        busiest = max(demand, key=lambda name: demand[name][0], default=None) if stopped > ready_at else None
        demand_pct, wait_pct = demand[busiest] if busiest else (None, None)
        # behind: a thread (the loop's, or libzmq's reading the connections) wanted a CPU most of the
        # time, or the bulk read typically started a whole period late (under half its cadence)
        saturated = ((demand_pct is not None and demand_pct >= DEMAND_SATURATED_PCT)
                     or (stopped > ready_at and lag_p50_ms > 1000.0 * self.spec.bulk_period_s))
        received, backlog = self.received, self.backlog
        return {"seconds": round(window, 2), "received": received, "cpu_s": round(cpu_window, 3),
                "cpu_pct": round(100.0 * cpu_window / window, 1),
                "cpu_us_per_message": round(1e6 * cpu_window / received, 2) if received else None,
                "busy_pct": busy_pct, "demand_pct": demand_pct, "runqueue_wait_pct": wait_pct,
                "demand_thread": busiest, "demand_pct_by_thread": {k: v[0] for k, v in demand.items()},
                "saturated": saturated,
                "backlog_p50": _percentile(backlog, 50), "backlog_p99": _percentile(backlog, 99),
                "backlog_max": int(np.flatnonzero(backlog).max()) if backlog.any() else 0,
                "turn_max_ms": round(1000.0 * self.turn_max, 2),
                "bulk_lag_ms": {"p50": round(lag_p50_ms, 2), "p99": round(float(np.percentile(lags_ms, 99)), 2),
                                "max": round(float(lags_ms.max()), 2)},
                "cpu_s_by_thread": threads}
