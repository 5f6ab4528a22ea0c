"""The watch task: N spectators and M players that take every message, and know when they could not.

Players send a zero force at input_hz (an arm at rest). Per snapshot the receipt time
(CLOCK_MONOTONIC) and tick go to SPEC "record" (.npz) for the latency; per client the snapshots,
the messages missed (gaps in the sequence numbers, swarm.tally), tick and score regressions,
goodbyes. A spectator subscribes to the feed its welcome names (its snapshots and events come
there, heartbeats and goodbye on the session). With "rejoin" a client silent for silence_s, or
told goodbye unknown_session, says hello again (a restarted gateway lost its sessions).

The receive loop waits on the sockets' ZMQ_FD descriptors with epoll, which costs per ready
socket, not per socket (zmq_poll over 500 sockets costs a few hundred microseconds a call), and
drains each socket without blocking, up to DRAIN_BATCH messages a visit. One spectator in
TIMED_EVERY (and every player and session) is timed: read as soon as its socket signals, its
snapshots' receipt times recorded for the latency. The other spectators' feeds are read in bulk
every BULK_PERIOD_S, a few snapshots a visit: each visit of a socket costs libzmq a wake-up and a
probe of the empty queue however many messages wait, so the bulk pays it once for several
(their counts and gaps are exact; their rates are timed to within the period). A snapshot or a
heartbeat is counted from its header alone (swarm.tally); one in VALIDATE_EVERY of them is
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

from processes.network.client import Client, Rejected
from processes.network.wire import GoodbyeReason, Kind, RejectReason
from processes.stress.probes import cpu_seconds, fd_count, rss_kb, thread_cpu_seconds, thread_sched_seconds
from processes.stress.swarm import NO_TOKEN, context, emit
from processes.stress.swarm.tally import Sequence, Tally, header

# A watch swarm's spectators read their feeds on libzmq I/O thread 1, the sessions stay on 0: with
# one thread, 250 feeds' 30,000 messages a second delayed the heartbeats out (as in the gateway).
FEED_OPTIONS = {zmq.AFFINITY: 1 << 1}
DRAIN_BATCH = 64  # messages read from one socket at one visit; the rest wait for the next turn
TIMED_EVERY = 20  # one spectator in this many is timed: read as soon as its socket signals
BULK_PERIOD_S = 0.05  # the other feeds are read this often, a few snapshots a visit
VALIDATE_EVERY = 500  # one snapshot in this many (of the process) is decoded in full
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


def _pin(spec: dict) -> None:
    """Pin this process to the CPU the spec names (every thread started after this inherits it):
    a swarm kept off the server's cores, or starved on purpose."""
    if spec.get("pin_cpu") is not None:
        os.sched_setaffinity(0, {spec["pin_cpu"]})


def _lower_priority(spec: dict) -> None:
    """Lower this process's priority by spec "nice", once its clients are in (they join at full
    speed): for the calling thread and for the session's autogroup, which holds every thread of
    the swarm (a session of its own); with autogroup scheduling (sched(7)) a nice value only
    weighs tasks of one session against each other."""
    if spec.get("nice"):
        os.nice(spec["nice"])
        try:
            with open("/proc/self/autogroup", "w") as f:
                f.write(str(spec["nice"]))
        except OSError:  # no autogroup scheduling here: the thread's nice value is what there is
            pass


def watch(spec: dict) -> dict:
    _pin(spec)
    n_spec, n_play = spec.get("spectators", 0), spec.get("players", 0)
    validate_every = spec.get("validate_every", VALIDATE_EVERY)
    timed_every = spec.get("timed_every", TIMED_EVERY)
    bulk_period_s = spec.get("bulk_period_s", BULK_PERIOD_S)
    fds_before = fd_count()
    zctx = context(2 * n_spec + n_play, io_threads=2)  # a spectator has two sockets: its session and its feed
    watchers = [_Watcher(Client(spec["address"], "spectator", f"{spec.get('name', 'w')}{i}", zctx=zctx,
                                feed_options=FEED_OPTIONS), "spectator") for i in range(n_spec)]
    watchers += [_Watcher(Client(spec["address"], "player", f"{spec.get('name', 'w')}p{i}", zctx=zctx), "player")
                 for i in range(n_play)]
    for i, w in enumerate(watchers):
        w.timed = w.role == "player" or i % timed_every == 0
    epoll = select.epoll()
    entries: dict[int, tuple] = {}  # ZMQ_FD -> (watcher, socket, on_feed), every socket
    bulk: dict[int, tuple] = {}  # the feeds read every bulk_period_s
    ready: dict[int, tuple] = {}  # sockets to drain this turn: signalled, or left with messages last turn

    def register(w: _Watcher, sock, on_feed: bool) -> int:
        fd = sock.get(zmq.FD)
        entries[fd] = (w, sock, on_feed)
        if on_feed and not w.timed:
            bulk[fd] = entries[fd]
        else:
            ready[fd] = entries[fd]  # drained once now: what came before signalled nobody
            epoll.register(fd, select.EPOLLIN)
        return fd

    def unregister(fd: int) -> None:
        entries.pop(fd, None)
        ready.pop(fd, None)
        if bulk.pop(fd, None) is None:
            try:
                epoll.unregister(fd)
            except (OSError, ValueError):  # closed already: epoll forgot it with the descriptor
                pass

    for w in watchers:
        w.session_fd = register(w, w.client.sock, False)
    rejected: Counter[str] = Counter()
    bad: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    ticks, times = array("q"), array("d")
    counts = {"score_regressions": 0, "events": 0, "received": 0, "sample_in": validate_every}
    silence_s = spec.get("silence_s", 1.0)
    input_dt = 1.0 / spec.get("input_hz", 50)
    join_deadline = time.monotonic() + spec.get("join_timeout", 30.0)
    for w in watchers:
        w.client.hello()
        w.hello_at = time.monotonic()
        w.hellos = 1
    ready_at = 0.0  # when every client was in (or the join deadline passed): the measured window starts
    started = time.monotonic()
    end = started + spec.get("duration", 10.0)
    rss_start = None
    next_sweep = next_bulk = 0.0
    last_sweep = 0.0
    sweep_gap = 0.0
    bulk_lags = array("d")
    done = set()
    all_finished = False
    waited = 0.0  # s spent waiting in epoll since ready
    turn_max = 0.0
    cpu_at_ready = 0.0
    threads_at_ready: dict[str, float] = {}
    sched_at_ready: dict[str, tuple[float, float]] = {}
    backlog = np.zeros(BACKLOG_BINS, np.int64)
    monotonic, recv_flags, again = time.monotonic, zmq.NOBLOCK, zmq.Again

    def finished(w: _Watcher) -> bool:
        return w.goodbye is not None or w in done

    def drain(fd: int, w: _Watcher, sock, on_feed: bool) -> int:
        """Read what waits on one socket, up to DRAIN_BATCH messages; how many were read."""
        client = w.client
        t = monotonic()
        timed = w.timed
        heartbeats = 0
        sample_in = counts["sample_in"]
        n = 0
        while n < DRAIN_BATCH:
            try:
                data = sock.recv(recv_flags)
            except again:
                break
            n += 1
            fixed = header(data)
            if fixed is not None:
                kind, seq, tick = fixed
                if kind == SNAPSHOT:
                    w.tally.snapshot(tick, t)
                    if timed:
                        ticks.append(tick)
                        times.append(t)
                    if tick > client.tick:
                        client.tick = tick
                elif on_feed:
                    bad["not_on_feed"] += 1  # only snapshots and events go out on the feed
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
                    sample_in = validate_every
                    message = client.drops.decode(data)
                    if message is None:
                        bad[Kind(kind).name.lower()] += 1
                    elif kind == SNAPSHOT:
                        score = (int(message["games_won"].sum()), int(message["score"].sum()))
                        counts["score_regressions"] += score < w.last_score
                        w.last_score = score
                continue
            message = client.drops.decode(data)
            if message is None:
                bad["other"] += 1
                continue
            seq = message.seq
            kinds[message.kind.name.lower()] += 1
            if on_feed:
                if message.kind != Kind.EVENT:
                    bad["not_on_feed"] += 1  # only snapshots and events go out on the feed
                    continue
                w.feed_seq.see(seq)
                counts["events"] += 1
                continue
            if message.kind in (Kind.WELCOME, Kind.REJECT):
                if w.feed is not None:  # a welcome may name a new feed: the old socket may close now
                    unregister(w.feed_fd)
                try:
                    client.accept(message)
                except Rejected as err:
                    rejected[err.reason.name.lower()] += 1
                    if err.reason == RejectReason.BAD_TOKEN:
                        client.token = NO_TOKEN  # a restarted gateway forgot it: ask for any seat
                    elif not spec.get("rejoin"):
                        done.add(w)
                    if w.feed is not None and client.feed is w.feed:
                        w.feed_fd = register(w, w.feed, True)
                    continue
                w.rejoined += w.welcomed
                w.welcomed = True
                w.session.last = seq
                w.last = t
                if client.feed is not w.feed:  # subscribed (or, after a restart, to a new port)
                    w.feed_seq.last = 0
                w.feed = client.feed
                if w.feed is not None:
                    w.feed_fd = register(w, w.feed, True)
                continue
            if message.kind == Kind.GOODBYE:
                if message["reason"] == GoodbyeReason.UNKNOWN_SESSION and spec.get("rejoin"):
                    client.hello()  # a restarted gateway lost our session: hello again now
                    w.hello_at = t
                    w.hellos += 1
                else:
                    w.goodbye = message["reason"].name.lower()
            elif message.kind == Kind.EVENT:
                counts["events"] += 1
            if w.welcomed:
                w.session.see(seq)
            w.last = t
        counts["sample_in"] = sample_in
        if heartbeats:
            kinds["heartbeat"] += heartbeats
        if ready_at:
            counts["received"] += n
        return n

    while True:
        before = monotonic()
        events_ready = epoll.poll(0 if ready else min(0.02, max(0.0, next_bulk - before)))
        now = monotonic()
        if ready_at:
            waited += now - before
        for fd, _ in events_ready:
            entry = entries.get(fd)
            if entry is not None:
                ready[fd] = entry
        batch = list(ready.items())
        ready.clear()
        for fd, entry in batch:
            if entries.get(fd) is None:
                continue  # unregistered by a message earlier in this turn (a welcome's new feed)
            n = drain(fd, *entry)
            if n == DRAIN_BATCH:
                ready[fd] = entry  # more may wait: its descriptor will not signal them again
            if ready_at:
                backlog[min(n, BACKLOG_BINS - 1)] += 1
        now = monotonic()
        if now >= next_bulk:
            if ready_at and next_bulk:
                bulk_lags.append(now - next_bulk)  # how late the bulk read started: the loop's lag
            next_bulk = now + bulk_period_s
            for fd, entry in list(bulk.items()):
                if fd in bulk:
                    drain(fd, *entry)
        turn = monotonic() - now
        now += turn
        if ready_at:
            turn_max = max(turn_max, turn)
        if now >= next_sweep:
            if ready_at and last_sweep:
                sweep_gap = max(sweep_gap, now - last_sweep)  # our own stalls: a heartbeat may be late by this
            last_sweep = now
            next_sweep = now + SWEEP_PERIOD_S
            all_finished = all(finished(w) for w in watchers)
            if not ready_at and (all(w.welcomed or finished(w) for w in watchers) or now > join_deadline):
                ready_at = now
                rss_start = rss_kb()
                cpu_at_ready = cpu_seconds()
                threads_at_ready = thread_cpu_seconds("self")
                sched_at_ready = thread_sched_seconds()
                _lower_priority(spec)
                emit({"event": "ready", "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
                      "fds": fd_count(), "t": now})
            for w in watchers:
                if finished(w):
                    continue
                client = w.client
                sent = client.seq
                if w.welcomed:
                    client.heartbeat_if_due()
                    if w.role == "player" and now >= w.next_input:
                        w.next_input = now + input_dt
                        client.send_input(np.zeros(6))
                        w.inputs += 1
                if spec.get("rejoin") and now - max(w.last, w.hello_at) > silence_s and w.hellos < 100:
                    client.hello()  # the gateway went silent: a restarted one needs a hello
                    w.hello_at = now
                    w.hellos += 1
                if client.seq != sent:  # a send may take the socket's read signal with it (zmq_getsockopt
                    ready[w.session_fd] = entries[w.session_fd]  # ZMQ_FD): drain it next turn all the same
        if now >= end or (spec.get("until_goodbye") and ready_at and all_finished):
            break
    stopped = time.monotonic()
    cpu_window = (cpu_seconds() or 0.0) - cpu_at_ready
    threads = {name: round(c - threads_at_ready.get(name, 0.0), 3) for name, c in thread_cpu_seconds("self").items()}
    sched_at_stop = thread_sched_seconds()
    if not ready_at:
        ready_at = stopped
        emit({"event": "ready", "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
              "fds": fd_count(), "t": stopped})
    if spec.get("leave_at_end", True):
        for w in watchers:
            if w.goodbye is None and w.welcomed:
                w.client.sock.setsockopt(zmq.LINGER, 1000)  # the goodbye leaves before the socket goes
                w.client.leave()
    rss_end = rss_kb()
    epoll.close()
    for w in watchers:
        w.client.close()
    zctx.term()
    fds_after = fd_count()
    if spec.get("record"):
        np.savez(spec["record"], ticks=np.frombuffer(ticks, np.int64), times=np.frombuffer(times, np.float64))
    welcome = next((w.client.welcome for w in watchers if w.client.welcome is not None), None)
    rates = [r for r in (w.tally.rate_hz() for w in watchers) if r is not None]
    window = max(stopped - ready_at, 1e-9)
    busy_pct = round(100.0 * (1.0 - waited / window), 1) if stopped > ready_at else None
    lags_ms = 1000.0 * np.frombuffer(bulk_lags, np.float64) if len(bulk_lags) else np.zeros(1)
    lag_p50_ms = float(np.percentile(lags_ms, 50))
    demand = {}  # per thread: % of the window on a CPU or runnable and waiting for one, and waiting
    for name, (on_cpu, waiting) in sched_at_stop.items():
        on0, wait0 = sched_at_ready.get(name, (0.0, 0.0))
        demand[name] = (round(100.0 * (on_cpu - on0 + waiting - wait0) / window, 1),
                        round(100.0 * (waiting - wait0) / window, 1))
    busiest = max(demand, key=lambda name: demand[name][0], default=None) if stopped > ready_at else None
    demand_pct, wait_pct = demand[busiest] if busiest else (None, None)
    # behind: a thread (the loop's, or libzmq's reading the connections) wanted a CPU most of the
    # time, or the bulk read typically started a whole period late (under half its cadence)
    saturated = ((demand_pct is not None and demand_pct >= DEMAND_SATURATED_PCT)
                 or (stopped > ready_at and lag_p50_ms > 1000.0 * bulk_period_s))
    received = counts["received"]
    return {"clients": len(watchers), "timed": sum(w.timed for w in watchers), "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
            "snapshots": sum(w.tally.snapshots for w in watchers), "missed": sum(w.session.missed for w in watchers),
            "missed_max": max((w.session.missed for w in watchers), default=0),
            "feed_missed": sum(w.feed_seq.missed for w in watchers),
            "feed_missed_max": max((w.feed_seq.missed for w in watchers), default=0),
            "on_feed": sum(w.feed is not None for w in watchers),
            "seq_resets": sum(w.session.resets for w in watchers), "rejoined": sum(w.rejoined for w in watchers),
            "hellos": sum(w.hellos for w in watchers), "inputs": sum(w.inputs for w in watchers),
            "goodbyes": dict(Counter(w.goodbye for w in watchers if w.goodbye)),
            "no_goodbye": sum(1 for w in watchers if w.goodbye is None and w.welcomed),
            "events": counts["events"], "messages": dict(kinds), "invalid": dict(bad),
            "decode_drops": {k: v for w in watchers for k, v in w.client.drops.by_reason.items()},
            "regressions": {"score": counts["score_regressions"], "tick": sum(w.tally.tick_regressions for w in watchers)},
            "rate_min": min(rates, default=0.0), "rate_median": float(np.median(rates)) if rates else 0.0,
            "rate_max": max(rates, default=0.0),
            "dt": float(welcome["dt"]) if welcome is not None else None,
            "seconds": stopped - started, "fds_before": fds_before, "fds_after": fds_after,
            "rss_start_kb": rss_start or rss_end, "rss_end_kb": rss_end,
            "last_tick": max((w.tally.last_tick for w in watchers), default=-1), "sweep_gap_max_s": round(sweep_gap, 3),
            "load": {"seconds": round(window, 2), "received": received, "cpu_s": round(cpu_window, 3),
                     "cpu_pct": round(100.0 * cpu_window / window, 1),
                     "cpu_us_per_message": round(1e6 * cpu_window / received, 2) if received else None,
                     "busy_pct": busy_pct, "demand_pct": demand_pct, "runqueue_wait_pct": wait_pct,
                     "demand_thread": busiest, "demand_pct_by_thread": {k: v[0] for k, v in demand.items()},
                     "saturated": saturated,
                     "backlog_p50": _percentile(backlog, 50), "backlog_p99": _percentile(backlog, 99),
                     "backlog_max": int(np.flatnonzero(backlog).max()) if backlog.any() else 0,
                     "turn_max_ms": round(1000.0 * turn_max, 2), "bulk_lag_ms": {"p50": round(lag_p50_ms, 2),
                     "p99": round(float(np.percentile(lags_ms, 99)), 2), "max": round(float(lags_ms.max()), 2)}, "cpu_s_by_thread": threads}}
