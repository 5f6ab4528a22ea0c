"""abuse: hostile peers, one at a time, against a served cloth match that honest spectators watch.

The default match (the cloth net in its own worker) is served with seat A remote (the flood
takes it; the match does not wait for it) and seat B the AI. Honest spectators watch it all on
the feed, each one timed (every snapshot's receipt time recorded). The gateway's RSS is sampled
throughout. In turn, after a quiet window that is the baseline: the attacks of swarm.abuse
(flood, multipart, oversized, hellos, slow), each for `--abuse-seconds`, then a quiet window
after them, then SIGTERM and SIGINT one after another on the server until it has exited.

Invariants (problems when broken):
- the gateway's RSS at most RSS_DURING_MB over its baseline during every attack, and within
  RSS_AFTER_MB of it in the quiet window after them (memory a closed peer held is given back);
- the honest spectators' snapshot rate during each attack at least HONEST_SHARE of their rate in
  the baseline window (the same run, the same spectators);
- no honest spectator refused; the probe (an honest spectator asking for a place while the
  hoarder's sockets hold every free one, a heartbeat period after their hellos) welcomed, at
  once or after the `retry in` a `full` reject names (hellos the hoarder said again within the
  last heartbeat period still hold their places);
- every multipart and oversized peer cut, each cut counted by reason in the gateway's counters;
- after the signals: the server's end line with the gateway's counters ("end" shutdown, every
  session told), every honest spectator told goodbye shutdown, no traceback, no segment left.
"""
from __future__ import annotations

import os
import signal
import statistics
import subprocess
import threading
import time

import numpy as np

from processes.stress.harness import Run, StressError
from processes.stress.probes import CpuMeter, rss_kb, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, watch_spec

SCENE = "match"
ATTACKS = ("flood", "multipart", "oversized", "hellos", "slow")
SPARE_PLACES = 8  # spectator places beyond the honest ones: what the hoarder can take
RSS_DURING_MB = 64
RSS_AFTER_MB = 16
HONEST_SHARE = 0.9
RSS_PERIOD_S = 0.02
HEARTBEAT_S = 0.25
SAFETY_S = 300.0  # every child's own bound beyond the run: a safety net, not a schedule


class RssSampler(threading.Thread):
    """The gateway's RSS every RSS_PERIOD_S, with its time (CLOCK_MONOTONIC)."""

    def __init__(self, pid: int):
        super().__init__(name="rss", daemon=True)
        self.pid = pid
        self.samples: list[tuple[float, int]] = []
        self.stop_flag = threading.Event()

    def run(self) -> None:
        while not self.stop_flag.wait(RSS_PERIOD_S):
            kb = rss_kb(self.pid)
            if kb is None:
                return
            self.samples.append((time.monotonic(), kb))

    def between(self, t0: float, t1: float) -> list[int]:
        return [kb for t, kb in self.samples if t0 <= t <= t1]

    def stop(self) -> None:
        self.stop_flag.set()
        self.join(5.0)


def _rate(times: np.ndarray, clients: int, t0: float, t1: float) -> float:
    """Snapshots a second per honest spectator received within [t0, t1]."""
    return float(np.count_nonzero((times >= t0) & (times <= t1))) / clients / max(t1 - t0, 1e-9)


def _ticks_per_s(clock: dict, t0: float, t1: float) -> float | None:
    """The match clock's pace within [t0, t1]: physics ticks a wall second (the server's tick log)."""
    inside = (clock["times"] >= t0) & (clock["times"] <= t1)
    if np.count_nonzero(inside) < 2:
        return None
    ticks, times = clock["ticks"][inside], clock["times"][inside]
    return round(float(ticks[-1] - ticks[0]) / max(float(times[-1] - times[0]), 1e-9), 1)


def _quiet(seconds: float) -> tuple[float, float]:
    """A window with no attack: the honest spectators' rate and the gateway's RSS are measured in it."""
    t0 = time.monotonic()
    time.sleep(seconds)
    return t0, time.monotonic()


def _attack(run: Run, name: str, server: Server, seconds: float) -> dict:
    spec = {"task": "abuse", "attack": name, "address": server.endpoint, "feed": server.feed, "seconds": seconds,
            "probe_after_s": max(2 * HEARTBEAT_S, seconds / 2)}
    child = run.add(launch(spec, f"abuse-{name}"))
    started = child.expect(lambda o: o.get("event") == "started", SAFETY_S, f"{name} started")
    report = child.expect(lambda o: o.get("event") == "report", seconds + SAFETY_S, f"{name} report")
    child.wait(30)
    return {**report, "t": started["t"]}


def _stop_with_signals(server: Server) -> int:
    """SIGTERM and SIGINT one after another until the server has exited; how many were sent."""
    sent, barrage = 0, (signal.SIGTERM, signal.SIGINT)
    deadline = time.monotonic() + SAFETY_S
    while server.proc.poll() is None and time.monotonic() < deadline:
        try:
            os.kill(server.pid, barrage[sent % 2])
        except ProcessLookupError:
            break
        sent += 1
        try:
            server.proc.wait(0.02)
        except subprocess.TimeoutExpired:  # still stopping: another one
            pass
    return sent


def scenario(args, run: Run) -> dict:
    result = base("abuse")
    shm_before = shm_names()
    honest_n, seconds = args.abuse_spectators, args.abuse_seconds
    server = run.add(Server(run.tmp, players=1, snapshot_hz=60, heartbeat_s=HEARTBEAT_S, timeout_s=2.0,
                            max_spectators=honest_n + SPARE_PLACES, players_timeout=0.0, scene=SCENE))
    gateway = server.pids["gateway"]
    record = os.path.join(run.tmp, "honest.npz")
    honest = run.add(launch(watch_spec(server.endpoint, honest_n, 0, "honest", record, timed_every=1,
                                       duration=SAFETY_S * 4, until_goodbye=True, leave_at_end=False), "honest"))
    honest.expect(lambda o: o.get("event") == "ready", SAFETY_S, "honest spectators ready")
    rss = RssSampler(gateway)
    rss.start()
    meter = CpuMeter()
    meter.start(server.all_pids())
    windows = {"baseline": _quiet(seconds)}
    reports = {}
    for name in ATTACKS:
        reports[name] = _attack(run, name, server, seconds)
        windows[name] = (reports[name]["t"], reports[name]["t_end"])
    windows["after"] = _quiet(seconds)
    stats_before_stop = server.gateway_stats()
    result["cpu_pct"] = meter.stop()
    signals = _stop_with_signals(server)
    rss.stop()
    try:
        end = server.finish(60)
    except StressError as err:
        end = {}
        result["problems"].append(f"no end line after the signals: {err}")
    honest_report = honest.expect(lambda o: o.get("event") == "report", 60, "honest report")
    with np.load(record) as data:
        times = data["times"]
    _judge(result, args, windows, reports, rss, times, honest_report, end, stats_before_stop, signals, server)
    return finish(result, run, server, shm_before, {})


def _judge(result, args, windows, reports, rss, times, honest_report, end, stats, signals, server) -> None:
    honest_n = args.abuse_spectators
    result["rate_problems"] = []  # the problems that are rates: a machine busy with other work breaks them too
    baseline_kb = statistics.median(rss.between(*windows["baseline"]) or [0])
    rates = {name: round(_rate(times, honest_n, *window), 2) for name, window in windows.items()}
    clock = server.tick_clock()
    ticks_per_s = {name: _ticks_per_s(clock, *window) for name, window in windows.items()} if clock else {}
    rss_mb = {name: round((max(rss.between(*window) or [baseline_kb]) - baseline_kb) / 1024, 1)
              for name, window in windows.items() if name != "baseline"}
    after_mb = round((statistics.median(rss.between(*windows["after"]) or [baseline_kb]) - baseline_kb) / 1024, 1)
    gateway = end.get("gateway", {})
    result["gateway"] = gateway
    result["rss_growth_pct"] = round(100.0 * after_mb * 1024 / baseline_kb, 2) if baseline_kb else None
    result["counts"] = {
        "honest_rate_hz": rates, "match_ticks_per_s": ticks_per_s, "honest_share": {name: round(rates[name] / rates["baseline"], 3)
                                                  for name in ATTACKS if rates["baseline"] > 0},
        "gateway_rss_baseline_mb": round(baseline_kb / 1024, 1), "gateway_rss_growth_max_mb": rss_mb,
        "gateway_rss_after_mb": after_mb, "attacks": {name: {k: v for k, v in r.items() if k not in ("t", "t_end", "event", "pid")}
                                                      for name, r in reports.items()},
        "signals_sent": signals, "honest_goodbyes": honest_report["goodbyes"],
        "honest_rejected": honest_report["rejected"],
        "counters": {k: stats.get(k, 0) for k in ("inputs_coalesced", "inputs_accepted", "disconnected.held_bytes",
                                                   "disconnected.too_many_connections", "evicted.unconfirmed",
                                                   "timeouts.unconfirmed", "dropped.hello_in_session",
                                                   "memory_trims", "feed_disconnected.held_bytes")}}
    for name in ATTACKS:
        check(result, rss_mb[name] <= RSS_DURING_MB,
              f"{name}: the gateway's RSS grew {rss_mb[name]} MB, more than {RSS_DURING_MB} MB")
        if rates["baseline"] > 0 and rates[name] < HONEST_SHARE * rates["baseline"]:
            problem = (f"{name}: honest spectators got {rates[name]} snapshots/s, under {HONEST_SHARE:.0%} of "
                       f"{rates['baseline']} without an attack")
            result["problems"].append(problem)
            result["rate_problems"].append(problem)
    check(result, rates["baseline"] > 0, "the honest spectators got no snapshot in the baseline window")
    check(result, after_mb <= RSS_AFTER_MB,
          f"after the attacks the gateway's RSS stayed {after_mb} MB above its baseline (at most {RSS_AFTER_MB})")
    check(result, not honest_report["rejected"], f"honest spectators refused: {honest_report['rejected']}")
    probe = reports["hellos"].get("probe", {})
    check(result, probe.get("answer") == "welcome", f"the probe among the hoarder's hellos: {probe}")
    multipart = reports["multipart"]
    check(result, multipart["cut"] == multipart["peers"], f"multipart peers cut: {multipart['cut']} of {multipart['peers']}")
    oversized = reports["oversized"]
    check(result, oversized.get("announced_cut", 0) == oversized.get("announced_1gib", 0)
          and oversized.get("big_frame_cut", 0) == oversized.get("big_frames", 0),
          f"oversized peers not all cut: {oversized}")
    check(result, stats.get("disconnected.held_bytes", 0) >= multipart["peers"],
          f"the gateway counted {stats.get('disconnected.held_bytes', 0)} cuts for held bytes, "
          f"{multipart['peers']} multipart peers were cut")
    check(result, bool(end), "the server printed no end line after the signals")
    check(result, gateway.get("end") == "shutdown" and gateway.get("goodbyes_at_end", 0) >= honest_n,
          f"the gateway's last counters after the signals: end {gateway.get('end')}, "
          f"goodbyes_at_end {gateway.get('goodbyes_at_end')}")
    check(result, honest_report["goodbyes"] == {"shutdown": honest_n},
          f"honest spectators ended {honest_report['goodbyes']}")
    check(result, "Traceback" not in server.stderr(), f"the server wrote a traceback: {server.stderr()[-1500:]}")
