"""malformed: N bad messages of every class; the gateway's counters must equal the sender's.

The gateway reports its counters at the end of the match; the sender computed each message's
counter with wire.decode on the same bytes.
"""
from __future__ import annotations

from processes.stress.harness import Run
from processes.stress.probes import CpuMeter, rss_kb, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, watch_spec


def scenario(args, run: Run) -> dict:
    result = base("malformed")
    shm_before = shm_names()
    n, rate = args.malformed, args.malformed_rate
    # The match must outlast the flood at its rate (4x: a loaded machine is slower) and the round
    # trips after it: the gateway reports its counters when the match ends. 20 s of margin: with
    # 9 s a cold-cache CI run (two test workers compiling) saw the match end before the round trips.
    seconds = n / rate * 4.0 + 20.0
    # A 30 s silence timeout: the flood's own player and watcher share a process with the flood,
    # and a cold-cache CI run starved their heartbeats past 5 s, so the gateway dropped them and
    # counted their later messages as sessionless (this scenario counts drops, not timeouts).
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=30.0, max_spectators=32, seconds=seconds))
    gateway = server.pids["gateway"]
    legit = run.add(launch(watch_spec(server.endpoint, 4, 1, "ok", None, duration=seconds + 120, until_goodbye=True),
                          "legit"))
    legit.expect(lambda o: o.get("event") == "ready", 60, "ready")
    rss0 = rss_kb(gateway)
    meter = CpuMeter()
    meter.start(server.all_pids())
    flood = run.add(launch({"task": "malformed", "address": server.endpoint, "n": n, "rate": rate, "seed": args.seed,
                           "max_seconds": seconds - 4.0}, "malformed"))
    report = flood.expect(lambda o: o.get("event") == "report", seconds + 60, "report")
    rss1 = rss_kb(gateway)
    result["cpu_pct"] = meter.stop()
    end = server.finish(seconds + 60)
    legit_report = legit.expect(lambda o: o.get("event") == "report", 30, "report")
    stats = end.get("gateway", {})
    result["gateway"] = stats
    sent, expected = report["sent"], report["expected"]
    kicks = sum(v for k, v in report["counts"].items() if k.startswith("kicked_seen."))
    mismatched = {k: (v, stats.get(k, 0)) for k, v in expected.items() if k.startswith("dropped.") and stats.get(k, 0) != v}
    refusals = {"refused.other_bat": sent.get("other_bat", 0), "refused.spectator_input": sent.get("spectator_input", 0),
                "refused.stale_input": sent.get("stale_replay", 0), "kicked": kicks}
    mismatched.update({k: (v, stats.get(k, 0)) for k, v in refusals.items() if stats.get(k, 0) != v})
    extra = {k: v for k, v in stats.items() if k.startswith("dropped.") and k not in expected}
    result["counts"] = {"sent": report["sent_total"], "by_class": sent, "gateway_dropped_total": stats.get("dropped_total"),
                        "expected_dropped_total": sum(v for k, v in expected.items() if k.startswith("dropped.")),
                        "kicks": kicks, "sessions": report["counts"], "seconds": round(report["seconds"], 1),
                        "legit_goodbyes": legit_report["goodbyes"], "legit_snapshots": legit_report["snapshots"],
                        "legit_inputs": legit_report["inputs"], "gateway_inputs_accepted": stats.get("inputs_accepted"),
                        "mismatched_counters": mismatched, "unexpected_counters": extra,
                        "synced": f"{report['synced_sockets']}/{report['sockets']} sockets, "
                                  f"{report['sessions_synced']}/2 sessions",
                        "unsynced": report.get("unsynced", []),
                        "late_replies_at_sync": report.get("late_replies_at_sync", {})}
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    result["lost_points"] = legit_report["regressions"]["score"] + legit_report["regressions"]["tick"]
    check(result, end.get("end") == "match_over", f"server ended {end.get('end')} (no gateway counters)")
    check(result, report["sent_total"] == n, f"{n - report['sent_total']} of {n} messages not sent")
    check(result, report["synced_sockets"] == report["sockets"] and report["sessions_synced"] == 2,
           f"round trips: {result['counts']['synced']} (unsynced: {result['counts']['unsynced']})")
    check(result, not mismatched, f"gateway counters differ from the sender's (expected, counted): {mismatched}")
    check(result, not extra, f"gateway counted drops nobody sent: {extra}")
    check(result, legit_report["goodbyes"] == {"match_over": 5}, f"legit clients ended {legit_report['goodbyes']}")
    fds = {"malformed": report["fds_after"] - report["fds_before"],
           "legit": legit_report["fds_after"] - legit_report["fds_before"]}
    return finish(result, run, server, shm_before, fds)
