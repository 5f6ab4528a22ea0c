"""churn: join/leave cycles, then every seat and spectator place must be free again.

Players claim and free seats, spectators come and go, some leave without goodbye; after it a fill
to exactly the limit is welcomed and one more is told "full".
"""
from __future__ import annotations

import time

from processes.stress.harness import Run, until
from processes.stress.probes import CpuMeter, fd_count, rss_kb, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, watch_spec


def scenario(args, run: Run) -> dict:
    result = base("churn")
    shm_before = shm_names()
    places = args.churn_places
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=1.0, grace_s=0.5, max_spectators=places))
    gateway = server.pids["gateway"]
    fds0 = fd_count(gateway)
    meter = CpuMeter()
    meter.start(server.all_pids())
    parts = [args.churn // 2, args.churn - args.churn // 2] if args.churn >= 100 else [args.churn]
    churners = [run.add(launch({"task": "churn", "address": server.endpoint, "cycles": c, "seed": i,
                               "concurrency": 8, "max_seconds": args.churn_seconds}, f"churn{i}"))
                for i, c in enumerate(parts)]
    churners[0].expect(lambda o: o.get("event") == "progress", args.churn_seconds, "first progress")
    rss0 = rss_kb(gateway)
    reports = [c.expect(lambda o: o.get("event") == "report", args.churn_seconds + 30, "report") for c in churners]
    rss1 = rss_kb(gateway)
    result["cpu_pct"] = meter.stop()
    churn_end = time.monotonic()
    counts: dict = {}
    for r in reports:
        for k, v in r["counts"].items():
            counts[k] = counts.get(k, 0) + v
    # every abrupt leaver is dropped after the timeout and its seat freed after the grace
    wait = server.spec["timeout_s"] + server.spec["grace_s"] + 1.0
    until(lambda: time.monotonic() - churn_end > wait, wait + 1)
    fill = run.add(launch(watch_spec(server.endpoint, places + 1, 3, "fill", duration=1.0, leave_at_end=True,
                                     join_timeout=20), "fill"))
    ready = fill.expect(lambda o: o.get("event") == "ready", 60, "fill ready")
    fill_report = fill.expect(lambda o: o.get("event") == "report", 60, "fill report")
    settled = until(lambda: fd_count(gateway) is not None and fd_count(gateway) <= fds0, 10)
    fds1 = fd_count(gateway)
    end = server.stop()
    cycles = sum(r["cycles"] for r in reports)
    result["counts"] = {"cycles": cycles, **counts, "fill_welcomed": ready["welcomed"], "fill_rejected": ready["rejected"],
                        "join_ms_p50": reports[0]["join_ms_p50"], "join_ms_p99": reports[0]["join_ms_p99"],
                        "seconds": round(max(r["seconds"] for r in reports), 1),
                        "cycles_per_s": round(cycles / max(max(r["seconds"] for r in reports), 1e-9), 1),
                        "gateway_fds_before": fds0, "gateway_fds_after": fds1,
                        "goodbyes_at_shutdown": fill_report["goodbyes"]}
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    check(result, cycles == args.churn, f"{args.churn - cycles} cycles not run")
    check(result, counts.get("join_timeouts", 0) == 0, f"{counts.get('join_timeouts')} joins got no answer")
    check(result, ready["welcomed"] == places + 2, f"after churn {ready['welcomed']} of {places} spectators + 2 "
                                                      "players welcomed: places leaked")
    check(result, ready["rejected"] == {"full": 2}, f"the extra spectator and player: {ready['rejected']}, "
                                                      "expected full for both")
    check(result, settled, f"gateway descriptors {fds0} before, {fds1} after")
    check(result, end.get("end") == "stopped", f"server ended {end.get('end')}")
    fds = {"gateway": (fds1 or 0) - (fds0 or 0), **{c.name: r["fds_after"] - r["fds_before"]
                                                    for c, r in zip(churners, reports)}}
    return finish(result, run, server, shm_before, fds)
