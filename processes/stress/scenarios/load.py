"""load: N spectators watch while two bots play a match of `duration` seconds.

Per-client snapshot rate, latency (server tick -> client receipt), snapshots missed, tick jitter,
CPU of every process and of the gateway's threads.
"""
from __future__ import annotations

import os
import time

import numpy as np

from processes.stress.harness import Run, StressError, bot, until
from processes.stress.probes import CpuMeter, cpu_seconds, rss_kb, shm_names
from processes.stress.report import jitter, latency
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, split, watch_spec


def scenario(args, run: Run) -> dict:
    result = base("load")
    shm_before = shm_names()
    n, seconds = args.spectators, args.duration
    fanout = getattr(args, "fanout", "pub")  # pub: the feed; router: one send per session (protocol 1's way)
    server = run.add(Server(run.tmp, players=2, snapshot_hz=args.hz, max_spectators=max(n, 1), seconds=seconds,
                            feed=fanout == "pub"))
    records = [os.path.join(run.tmp, f"load-{i}.npz") for i in range(len(split(n)))]
    swarms = [run.add(launch(watch_spec(server.endpoint, k, 0, f"s{i}_", records[i], duration=seconds + 120,
                                        until_goodbye=True), f"swarm{i}")) for i, k in enumerate(split(n)) if k]
    readies = [s.expect(lambda o: o.get("event") == "ready", 60 + n / 20, "ready") for s in swarms]
    if getattr(args, "still_players", False):  # players that hold their bats still: the fan-out alone
        bots = [run.add(launch(watch_spec(server.endpoint, 0, 2, "still", None, duration=seconds + 120,
                                          until_goodbye=True), "still_players"))]
    else:
        bots = [run.add(bot(server.endpoint, seconds + 120, seed)) for seed in range(args.players)]
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
    published = server.gateway_stats().get("snapshots_published", 0) - published0
    if published > 0 and result["cpu_pct"].get("gateway") is not None:
        # the gateway's CPU (both threads) per snapshot published while the meter ran, and per copy
        # to one subscriber: what the fan-out costs the server, startup and the join phase left out
        us = 1e4 * result["cpu_pct"]["gateway"] * result["cpu_pct"]["_wall_s"] / published
        result["gateway_cpu_us"] = {"per_snapshot": round(us, 1), "per_snapshot_per_spectator": round(us / max(n, 1), 2),
                                    "published_while_metered": published}
    # the gateway counts as its whole process here; its threads are listed apart in cpu_pct
    sides = {"server": set(server.all_pids()), "swarm": {s.name for s in swarms}, "players": {b.name for b in bots}}
    result["cpu_pct_by_side"] = {side: round(sum(v or 0.0 for k, v in result["cpu_pct"].items() if k in names), 1)
                                 for side, names in sides.items()}
    t1 = time.monotonic()
    end = server.finish(60)
    reports = [s.expect(lambda o: o.get("event") == "report", 60, "report") for s in swarms]
    bot_reports = []
    for b in bots:
        try:
            if b.name == "still_players":
                report = b.expect(lambda o: o.get("event") == "report", 30, "report")
                bot_reports.append({"slot": "a+b", "goodbye": next(iter(report["goodbyes"]), "server_lost"),
                                    "snapshots": report["snapshots"], "inputs_sent": report["inputs"]})
                continue
            bot_reports.append(b.expect(lambda o: "goodbye" in o, 30, "summary"))
            b.wait(10)
        except StressError:  # still reading behind, long after the match: a finding, then killed
            b.kill()
            bot_reports.append({"goodbye": "still_running", "tick": None})
    late = [r for r in bot_reports if r.get("goodbye") in ("server_lost", "still_running")]
    if late:  # `pingpong join` exits 1 when its server went silent without a goodbye
        result["findings"].append(
            f"{len(late)} bot(s) got no goodbye and ended by timeout or were still reading 30 s on (last tick read "
            f"{[r.get('tick') for r in late]} of {ticks}); the gateway sends its goodbye without blocking (dropped "
            "at the high-water mark like a snapshot) and closes its socket with linger 0 right after (a goodbye "
            "still queued is discarded), so a peer reading behind can miss it")
    clock = server.tick_clock()
    result["latency_ms"] = latency(clock, server.dt, records)
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    stats = end.get("gateway", {})
    result["gateway"] = stats
    welcomed = sum(r["welcomed"] for r in reports)
    snapshots = sum(r["snapshots"] for r in reports)
    missed = sum(r["missed"] for r in reports)
    feed_missed = sum(r.get("feed_missed", 0) for r in reports)
    on_feed = sum(r.get("on_feed", 0) for r in reports)
    goodbyes = sum(r["goodbyes"].get("match_over", 0) for r in reports)
    result["counts"] = {
        "spectators": n, "welcomed": welcomed, "rejected": sum(sum(r["rejected"].values()) for r in readies),
        "fanout": fanout, "on_feed": on_feed, "feed": server.feed,
        "snapshot_hz": args.hz, "snapshots_received": snapshots, "snapshots_missed": missed + feed_missed,
        "feed_missed": feed_missed, "feed_missed_max": max((r.get("feed_missed_max", 0) for r in reports), default=0),
        "session_messages_missed": missed,
        "gateway_snapshots_published": stats.get("snapshots_published", 0),
        "gateway_snapshots_sent": stats.get("snapshots_sent"), "gateway_snapshots_dropped": stats.get("snapshots_dropped", 0),
        "rate_min_hz": round(min(r["rate_min"] for r in reports), 1) if reports else None,
        "rate_median_hz": round(float(np.median([r["rate_median"] for r in reports])), 1) if reports else None,
        "goodbye_match_over": goodbyes, "bots_without_goodbye": len(late), "bots": [{k: r.get(k) for k in ("slot", "goodbye", "snapshots", "inputs_sent")}
                                                  for r in bot_reports],
        "points": end.get("final", {}).get("points_total"), "match_ticks": end.get("summary", {}).get("ticks"),
        "score_regressions": sum(r["regressions"]["score"] for r in reports),
        "tick_regressions": sum(r["regressions"]["tick"] for r in reports),
        "invalid_snapshots": sum(sum(r["invalid"].values()) for r in reports),
        "gateway_timeouts": stats.get("timeouts", 0),
        "swarm_heartbeat_gap_max_s": max((r.get("sweep_gap_max_s", 0.0) for r in reports), default=0.0),
    }
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
    result["counts"]["gateway_snapshots_unencodable"] = stats.get("snapshots_unencodable", 0)
    result["counts"]["unencodable_examples"] = end.get("unencodable_examples", {})
    result["counts"]["states_beyond_wire_ranges"] = f"{sum(end.get('unencodable', {}).values())} of " \
                                                    f"{end.get('encode_checked')} checked"
    if stats.get("snapshots_unencodable"):
        result["findings"].append(
            f"the gateway could not encode {stats['snapshots_unencodable']} snapshots (the state was beyond the "
            f"wire's ranges, e.g. {next(iter(end.get('unencodable_examples', {}).values()), '?')}): no snapshot went "
            "out for those slots, so the per-client rate is below the snapshot rate")
    result["lost_points"] = result["counts"]["score_regressions"] + result["counts"]["tick_regressions"]
    check(result, welcomed == n, f"{n - welcomed} spectators not welcomed")
    if fanout == "pub":
        check(result, on_feed == welcomed, f"{welcomed - on_feed} of {welcomed} spectators not on the feed")
    check(result, goodbyes == welcomed, f"{welcomed - goodbyes} spectators without the match_over goodbye")
    check(result, end.get("end") == "match_over", f"server ended {end.get('end')}")
    check(result, result["counts"]["invalid_snapshots"] == 0, "snapshots failed validation")
    fds = {s.name: r["fds_after"] - r["fds_before"] for s, r in zip(swarms, reports)}
    timed_out = {b.pid for b, r in zip(bots, bot_reports)
                 if (r.get("goodbye") == "server_lost" and b.proc.poll() == 1) or r.get("goodbye") == "still_running"}
    return finish(result, run, server, shm_before, fds, expected_dead=timed_out)
