"""load: N spectators watch while two bots play a match of `duration` seconds.

Per-client snapshot rate, latency (from the tick's scheduled time to the client's receipt, so a
client that fell behind is charged for it: no coordinated omission), snapshots missed, tick
jitter, CPU of every process and of the gateway's threads, and the swarm's own load: its CPU per
message received, how busy its receive loops were, the backlog they found; a result is marked
`limited_by_load_generator` when a swarm process was saturated, so its rates are its own limit.

The two sides can run apart: `--server-only` serves the match and starts the players once the
spectators are in; `--swarm-only --target ADDRESS` runs just the spectators against it (on
another host, latency is taken against the fastest snapshot: the two clocks are not shared).
"""
from __future__ import annotations

import json
import os
import time

import numpy as np

from processes.stress.harness import Child, Run, StressError, bot, until
from processes.stress.probes import CpuMeter, cpu_seconds, rss_kb, shm_names
from processes.stress.report import gateway_latency, jitter, latency, latency_values, plot_load
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, split, watch_spec

JOIN_WAIT_S = 300.0  # --server-only: how long the server waits for its spectators before the match


def split_cores(cores: list[int]) -> tuple[list[int], list[int]] | None:
    """The server's cores and the load generator's, apart, when there are 4 or more (the first
    half for the server: its physics, net, AI and gateway workers); None with fewer."""
    if len(cores) < 4:
        return None
    half = len(cores) // 2
    return cores[:half], cores[half:]


def _pin_server(server: Server) -> dict | None:
    """Keep the server and the load generator on cores of their own where the machine has enough
    (split_cores): the server's processes are pinned here, the generator's at their start."""
    apart = split_cores(sorted(os.sched_getaffinity(0)))
    if apart is None:
        return None
    for pid in server.all_pids().values():
        try:
            os.sched_setaffinity(pid, apart[0])
        except ProcessLookupError:
            pass
    return {"server": apart[0], "generator": apart[1]}


def _swarms(args, run: Run, endpoint: str, seconds: float,
            cores: dict | None = None) -> tuple[list[Child], list[str], list[dict]]:
    """The spectators' swarm processes, their latency records, and their ready lines."""
    n = args.spectators
    schedule = getattr(args, "swarm_schedule", None) or {}  # pin_cpu, nice: see swarm.watch
    records = [os.path.join(run.tmp, f"load-{i}.npz") for i in range(len(split(n)))]

    def pinned(i: int) -> dict:
        if cores is None or "pin_cpu" in schedule:
            return schedule
        return {**schedule, "pin_cpu": cores["generator"][i % len(cores["generator"])]}

    swarms = [run.add(launch(watch_spec(endpoint, k, 0, f"s{i}_", records[i], duration=seconds + 120,
                                        until_goodbye=True, join_timeout=60 + n / 20, **pinned(i)), f"swarm{i}"))
              for i, k in enumerate(split(n)) if k]
    readies = [s.expect(lambda o: o.get("event") == "ready", 90 + n / 20, "ready") for s in swarms]
    return swarms, records, readies


def _players(args, run: Run, endpoint: str, seconds: float) -> list[Child]:
    if getattr(args, "still_players", False):  # players that hold their bats still: the fan-out alone
        return [run.add(launch(watch_spec(endpoint, 0, 2, "still", None, duration=seconds + 120,
                                          until_goodbye=True), "still_players"))]
    return [run.add(bot(endpoint, seconds + 120, seed)) for seed in range(args.players)]


def _player_reports(bots: list[Child]) -> list[dict]:
    reports = []
    for b in bots:
        try:
            if b.name == "still_players":
                report = b.expect(lambda o: o.get("event") == "report", 30, "report")
                reports.append({"slot": "a+b", "goodbye": next(iter(report["goodbyes"]), "server_lost"),
                                "snapshots": report["snapshots"], "inputs_sent": report["inputs"]})
                continue
            reports.append(b.expect(lambda o: "goodbye" in o, 30, "summary"))
            b.wait(10)
        except StressError:  # still reading behind, long after the match: a finding, then killed
            b.kill()
            reports.append({"goodbye": "still_running", "tick": None})
    return reports


def generator(reports: list[dict], names: list[str]) -> dict:
    """The swarm's own load, over its processes' measured windows: CPU per message received (every
    thread), the busiest receive loop, the largest backlog, and which processes were saturated."""
    loads = [r.get("load", {}) for r in reports]
    received = sum(x.get("received", 0) for x in loads)
    cpu_s = sum(x.get("cpu_s", 0.0) for x in loads)
    by_thread: dict[str, float] = {}
    for x in loads:  # libzmq's I/O threads apart from the Python one
        for thread, seconds in x.get("cpu_s_by_thread", {}).items():
            kind = "python" if thread == "python" else thread.rstrip("0123456789").rstrip("/")
            by_thread[kind] = by_thread.get(kind, 0.0) + seconds
    return {"processes": len(loads), "received": received,
            "cpu_us_per_message": round(1e6 * cpu_s / received, 2) if received else None,
            "cpu_us_per_message_by_thread": {k: round(1e6 * v / received, 2) for k, v in by_thread.items()}
            if received else {},
            "cpu_pct": {name: x.get("cpu_pct") for name, x in zip(names, loads)},
            "busy_pct_max": max((x.get("busy_pct") or 0.0 for x in loads), default=None),
            "demand_pct_max": max((x.get("demand_pct") or 0.0 for x in loads), default=None),
            "runqueue_wait_pct_max": max((x.get("runqueue_wait_pct") or 0.0 for x in loads), default=None),
            "backlog_p99_max": max((x.get("backlog_p99", 0) for x in loads), default=0),
            "backlog_max": max((x.get("backlog_max", 0) for x in loads), default=0),
            "turn_max_ms": max((x.get("turn_max_ms", 0.0) for x in loads), default=0.0),
            "bulk_lag_p50_ms_max": max((x.get("bulk_lag_ms", {}).get("p50", 0.0) for x in loads), default=0.0),
            "demand_thread": {name: x.get("demand_thread") for name, x in zip(names, loads)},
            "saturated": [name for name, x in zip(names, loads) if x.get("saturated")]}


def _spectators(args, reports: list[dict], readies: list[dict]) -> dict:
    """What the spectators counted, summed over the swarm processes."""
    welcomed = sum(r["welcomed"] for r in reports)
    missed = sum(r["missed"] for r in reports)
    feed_missed = sum(r.get("feed_missed", 0) for r in reports)
    snapshots = sum(r["snapshots"] for r in reports)
    return {
        "spectators": args.spectators, "welcomed": welcomed,
        "rejected": sum(sum(r["rejected"].values()) for r in readies),
        "on_feed": sum(r.get("on_feed", 0) for r in reports), "snapshot_hz": args.hz,
        "snapshots_received": snapshots, "snapshots_missed": missed + feed_missed,
        "missed_pct": round(100.0 * (missed + feed_missed) / max(snapshots + missed + feed_missed, 1), 3),
        "feed_missed": feed_missed, "feed_missed_max": max((r.get("feed_missed_max", 0) for r in reports), default=0),
        "session_messages_missed": missed,
        "rate_min_hz": round(min(r["rate_min"] for r in reports), 1) if reports else None,
        "rate_median_hz": round(float(np.median([r["rate_median"] for r in reports])), 1) if reports else None,
        "goodbye_match_over": sum(r["goodbyes"].get("match_over", 0) for r in reports),
        "score_regressions": sum(r["regressions"]["score"] for r in reports),
        "tick_regressions": sum(r["regressions"]["tick"] for r in reports),
        "invalid_snapshots": sum(sum(r["invalid"].values()) for r in reports),
        "swarm_heartbeat_gap_max_s": max((r.get("sweep_gap_max_s", 0.0) for r in reports), default=0.0),
    }


def _judge_spectators(result: dict, generated: dict) -> None:
    c = result["counts"]
    result["swarm"] = generated
    result["limited_by_load_generator"] = bool(generated["saturated"])
    if generated["saturated"]:
        result["findings"].append(
            f"limited by the load generator: swarm process(es) {', '.join(generated['saturated'])} fell behind "
            f"(receive loops wanting a CPU up to {generated['demand_pct_max']} % of the time, "
            f"{generated['runqueue_wait_pct_max']} % waiting for one, bulk reads late p50 up to "
            f"{generated['bulk_lag_p50_ms_max']} ms, backlog p99 {generated['backlog_p99_max']}): the rates, "
            "misses and latency describe the swarm, not the server")
    check(result, c["welcomed"] == c["spectators"], f"{c['spectators'] - c['welcomed']} spectators not welcomed")
    check(result, c["goodbye_match_over"] == c["welcomed"],
          f"{c['welcomed'] - c['goodbye_match_over']} spectators without the match_over goodbye")
    check(result, c["invalid_snapshots"] == 0, "snapshots failed validation")


def _plots(args, result: dict, values_s: np.ndarray, records: list[str], reports: list[dict]) -> None:
    if getattr(args, "plots", None):
        result["plots"] = plot_load(args.plots, values_s, records, args.hz, args.spectators,
                                    sum(r.get("timed", 0) for r in reports))


def scenario(args, run: Run) -> dict:
    if getattr(args, "target", None):
        return _swarm_only(args, run)
    if getattr(args, "server_only", False):
        return _server_only(args, run)
    result = base("load")
    shm_before = shm_names()
    n, seconds = args.spectators, args.duration
    fanout = getattr(args, "fanout", "pub")  # pub: the feed; router: one send per session (protocol 1's way)
    server = run.add(Server(run.tmp, players=2, snapshot_hz=args.hz, max_spectators=max(n, 1), seconds=seconds,
                            feed=fanout == "pub"))
    cores = _pin_server(server)
    swarms, records, readies = _swarms(args, run, server.endpoint, seconds, cores)
    bots = _players(args, run, server.endpoint, seconds)
    if cores is not None:
        for player in bots:
            os.sched_setaffinity(player.pid, cores["generator"])
    result["cores"] = cores or f"shared: {os.cpu_count()} cores are too few to keep the load generator apart"
    until(lambda: (server.tick() or 0) > 0, 120, 0.2)
    gateway = server.pids["gateway"]
    meter = CpuMeter(threads=("gateway",))
    meter.start({**server.all_pids(), **{s.name: s.pid for s in swarms}, **{b.name: b.pid for b in bots},
                 "harness": os.getpid()})
    published0 = server.gateway_stats().get("snapshots_published", 0)
    t0 = time.monotonic()
    rss0 = rss_kb(gateway)
    ticks = server.spec["ticks"]
    until(lambda: (server.tick() or ticks) >= 0.9 * ticks, seconds + 60, 0.25)
    rss1 = rss_kb(gateway)
    gateway_cpu = cpu_seconds(gateway)  # its whole life so far: set against every message it sent
    result["cpu_pct"] = meter.stop()
    _gateway_cost(result, server.gateway_stats().get("snapshots_published", 0) - published0, n)
    # the gateway counts as its whole process here; its threads are listed apart in cpu_pct
    sides = {"server": set(server.all_pids()), "swarm": {s.name for s in swarms}, "players": {b.name for b in bots}}
    result["cpu_pct_by_side"] = {side: round(sum(v or 0.0 for k, v in result["cpu_pct"].items() if k in names), 1)
                                 for side, names in sides.items()}
    t1 = time.monotonic()
    end = server.finish(60)
    # A swarm starved of CPU drains its backlog before it sees the goodbye: it reports at the latest
    # when its own bound (duration + 120 s from its start) ends its loop.
    reports = [s.expect(lambda o: o.get("event") == "report", seconds + 180, "report") for s in swarms]
    bot_reports = _player_reports(bots)
    late = _late_players(result, bot_reports, ticks)
    clock = server.tick_clock()
    values = latency_values(clock, server.dt, records)
    result["latency_ms"] = latency(values)
    result["gateway_latency_ms"] = gateway_latency(clock, server.send_log())  # the server's own part of it
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    stats = end.get("gateway", {})
    result["gateway"] = stats
    result["counts"] = {**_spectators(args, reports, readies), "fanout": fanout, "feed": server.feed,
                        **_server_counts(end, stats),
                        "bots_without_goodbye": len(late),
                        "bots": [{k: r.get(k) for k in ("slot", "goodbye", "snapshots", "inputs_sent")}
                                 for r in bot_reports]}
    _gateway_cpu(result, gateway_cpu, stats, n)
    _unencodable(result, end, stats)
    result["lost_points"] = result["counts"]["score_regressions"] + result["counts"]["tick_regressions"]
    _judge_spectators(result, generator(reports, [s.name for s in swarms]))
    if fanout == "pub":
        c = result["counts"]
        check(result, c["on_feed"] == c["welcomed"], f"{c['welcomed'] - c['on_feed']} of {c['welcomed']} spectators "
                                                     "not on the feed")
    check(result, end.get("end") == "match_over", f"server ended {end.get('end')}")
    _plots(args, result, values, records, reports)
    fds = {s.name: r["fds_after"] - r["fds_before"] for s, r in zip(swarms, reports)}
    timed_out = {b.pid for b, r in zip(bots, bot_reports)
                 if (r.get("goodbye") == "server_lost" and b.proc.poll() == 1) or r.get("goodbye") == "still_running"}
    return finish(result, run, server, shm_before, fds, expected_dead=timed_out)


def _server_only(args, run: Run) -> dict:
    """The server side alone: serve, announce the address, wait for the spectators, then play."""
    result = base("load")
    shm_before = shm_names()
    n, seconds = args.spectators, args.duration
    server = run.add(Server(run.tmp, players=2, snapshot_hz=args.hz, max_spectators=max(n, 1), seconds=seconds,
                            bind=getattr(args, "bind", None) or "tcp://127.0.0.1:0",
                            players_timeout=JOIN_WAIT_S + 60))
    print(json.dumps({"listening": server.endpoint, "spectators": n}) if args.json else
          f"pingpong stress: serving on {server.endpoint}; waiting for {n} spectators "
          f"(pingpong stress --swarm-only --target ADDRESS --spectators {n})", flush=True)
    joined = until(lambda: server.gateway_stats().get("spectators", 0) >= n, JOIN_WAIT_S, 0.25)
    bots = _players(args, run, server.endpoint, seconds)
    until(lambda: (server.tick() or 0) > 0, 120, 0.2)
    meter = CpuMeter(threads=("gateway",))
    meter.start({**server.all_pids(), **{b.name: b.pid for b in bots}})
    t0 = time.monotonic()
    ticks = server.spec["ticks"]
    until(lambda: (server.tick() or ticks) >= 0.9 * ticks, seconds + 60, 0.25)
    result["cpu_pct"] = meter.stop()
    t1 = time.monotonic()
    end = server.finish(60)
    bot_reports = _player_reports(bots)
    late = _late_players(result, bot_reports, ticks)
    clock = server.tick_clock()
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    result["gateway_latency_ms"] = gateway_latency(clock, server.send_log())  # the server's own part of the latency
    stats = end.get("gateway", {})
    result["gateway"] = stats
    result["counts"] = {"spectators": n, "spectators_joined": stats.get("spectators_joined", 0), "snapshot_hz": args.hz,
                        **_server_counts(end, stats), "bots_without_goodbye": len(late)}
    _unencodable(result, end, stats)
    check(result, joined, f"{n} spectators did not join within {JOIN_WAIT_S:.0f} s")
    check(result, end.get("end") == "match_over", f"server ended {end.get('end')}")
    timed_out = {b.pid for b, r in zip(bots, bot_reports)
                 if (r.get("goodbye") == "server_lost" and b.proc.poll() == 1) or r.get("goodbye") == "still_running"}
    return finish(result, run, server, shm_before, {}, expected_dead=timed_out)


def _swarm_only(args, run: Run) -> dict:
    """The spectators alone, against a server elsewhere: they stay until it says the match is over."""
    result = base("load")
    seconds = args.duration + JOIN_WAIT_S  # the match starts when the server has every spectator
    swarms, records, readies = _swarms(args, run, args.target, seconds)
    meter = CpuMeter()
    meter.start({s.name: s.pid for s in swarms})
    reports = [s.expect(lambda o: o.get("event") == "report", seconds + 180, "report") for s in swarms]
    result["cpu_pct"] = meter.stop()
    dt = next((r["dt"] for r in reports if r.get("dt")), None)
    values = np.zeros(0)
    if dt:  # no shared clock with the server: latency above the fastest snapshot's
        ticks = np.concatenate([np.load(p)["ticks"] for p in records if os.path.exists(p)] or [np.zeros(0, np.int64)])
        times = np.concatenate([np.load(p)["times"] for p in records if os.path.exists(p)] or [np.zeros(0)])
        order = np.argsort(times)
        clock = {"ticks": ticks[order], "times": times[order], "pids": np.zeros(len(ticks), np.int64),
                 "samples": len(ticks)}
        values = latency_values(clock, dt, records)
    result["latency_ms"] = latency(values)
    result["latency_reference"] = "fastest snapshot"
    result["counts"] = {**_spectators(args, reports, readies), "target": args.target}
    result["lost_points"] = result["counts"]["score_regressions"] + result["counts"]["tick_regressions"]
    _judge_spectators(result, generator(reports, [s.name for s in swarms]))
    _plots(args, result, values, records, reports)
    fds = {s.name: r["fds_after"] - r["fds_before"] for s, r in zip(swarms, reports)}
    return finish(result, run, None, set(), fds)


def _late_players(result: dict, bot_reports: list[dict], ticks: int) -> list[dict]:
    late = [r for r in bot_reports if r.get("goodbye") in ("server_lost", "still_running")]
    if late:  # `pingpong join` exits 1 when its server went silent without a goodbye
        result["findings"].append(
            f"{len(late)} bot(s) got no goodbye and ended by timeout or were still reading 30 s on (last tick read "
            f"{[r.get('tick') for r in late]} of {ticks}); the gateway sends its goodbye without blocking (dropped "
            "at the high-water mark like a snapshot) and closes its socket with linger 0 right after (a goodbye "
            "still queued is discarded), so a peer reading behind can miss it")
    return late


def _server_counts(end: dict, stats: dict) -> dict:
    return {"gateway_snapshots_published": stats.get("snapshots_published", 0),
            "gateway_snapshots_sent": stats.get("snapshots_sent"),
            "gateway_snapshots_dropped": stats.get("snapshots_dropped", 0),
            "points": end.get("final", {}).get("points_total"), "match_ticks": end.get("summary", {}).get("ticks"),
            "gateway_timeouts": stats.get("timeouts", 0)}


def _gateway_cost(result: dict, published: int, n: int) -> None:
    if published > 0 and result["cpu_pct"].get("gateway") is not None:
        # the gateway's CPU (both threads) per snapshot published while the meter ran, and per copy
        # to one subscriber: what the fan-out costs the server, startup and the join phase left out
        us = 1e4 * result["cpu_pct"]["gateway"] * result["cpu_pct"]["_wall_s"] / published
        result["gateway_cpu_us"] = {"per_snapshot": round(us, 1), "per_snapshot_per_spectator": round(us / max(n, 1), 2),
                                    "published_while_metered": published}


def _gateway_cpu(result: dict, gateway_cpu: float | None, stats: dict, n: int) -> None:
    sends = sum(v for k, v in stats.items() if k.endswith("_sent") or k.endswith("_published"))
    if gateway_cpu and stats.get("snapshots_published"):
        # the feed: the gateway's whole CPU per snapshot it published (the session traffic included)
        result["counts"]["gateway_cpu_us_per_snapshot"] = round(1e6 * gateway_cpu / stats["snapshots_published"], 1)
    elif gateway_cpu and sends:
        # the fan-out's own ceiling: one gateway process on one core sends this many snapshots a
        # second to each of n sessions (its CPU per message sent, heartbeats and polls included)
        per_send_us = 1e6 * gateway_cpu / sends
        result["counts"]["gateway_cpu_us_per_message"] = round(per_send_us, 1)
        result["counts"]["fanout_ceiling_hz_one_core"] = round(1e6 / (per_send_us * max(n, 1)), 1)


def _unencodable(result: dict, end: dict, stats: dict) -> None:
    result["counts"]["gateway_snapshots_unencodable"] = stats.get("snapshots_unencodable", 0)
    result["counts"]["unencodable_examples"] = end.get("unencodable_examples", {})
    result["counts"]["states_beyond_wire_ranges"] = f"{sum(end.get('unencodable', {}).values())} of " \
                                                    f"{end.get('encode_checked')} checked"
    if stats.get("snapshots_unencodable"):
        result["findings"].append(
            f"the gateway could not encode {stats['snapshots_unencodable']} snapshots (the state was beyond the "
            f"wire's ranges, e.g. {next(iter(end.get('unencodable_examples', {}).values()), '?')}): no snapshot went "
            "out for those slots, so the per-client rate is below the snapshot rate")
