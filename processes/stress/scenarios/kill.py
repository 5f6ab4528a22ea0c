"""kill: SIGKILL a swarm process and a bot mid-match, then the gateway, then the physics worker.

The supervisor restarts each, clients join again, no point is lost; then every slot is filled and
the server shut down: every client gets goodbye.
"""
from __future__ import annotations

import os
import signal
import time

from processes.stress.harness import Run, StressError, until
from processes.stress.probes import CpuMeter, shm_names
from processes.stress.report import jitter, latency, latency_values
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, watch_spec


def scenario(args, run: Run) -> dict:
    result = base("kill")
    shm_before = shm_names()
    n = max(args.kill_spectators, 2)
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=2.0, grace_s=1.0, max_spectators=n))
    records = [os.path.join(run.tmp, f"kill-{i}.npz") for i in range(3)]
    keep = run.add(launch(watch_spec(server.endpoint, n // 2, 0, "keep", records[0], duration=300, rejoin=True,
                                     until_goodbye=True, silence_s=1.0), "keep"))
    doomed = [run.add(launch(watch_spec(server.endpoint, max(1, (n - n // 2) // args.kill), 0, f"doom{i}", None,
                                        duration=300), f"doomed{i}")) for i in range(args.kill)]
    players = run.add(launch(watch_spec(server.endpoint, 0, 2, "pl", None, duration=300), "players"))
    for s in (keep, *doomed, players):
        s.expect(lambda o: o.get("event") == "ready", 60, "ready")
    if not until(lambda: server.state()["tick"] > 300, 120, 0.2):
        raise StressError("the match did not start")
    meter = CpuMeter()
    meter.start({**server.all_pids(), "keep": keep.pid})
    t0 = time.monotonic()
    counts: dict = {}
    for s in (*doomed, players):  # client processes die mid-match, the players' one too
        s.kill()
    counts["client_processes_killed"] = len(doomed) + 1
    before = server.state()
    os.kill(before["pids"]["gateway"], signal.SIGKILL)
    counts["gateway_restarted"] = until(lambda: server.state()["restarts"].get("gateway", 0) >= 1
                                        and server.state()["tick"] > before["tick"] + 200, 60, 0.2)
    mid = server.state()
    os.kill(mid["pids"]["physics"], signal.SIGKILL)
    counts["physics_restarted"] = until(lambda: server.state()["restarts"].get("physics", 0) >= 1
                                        and server.state()["tick"] > mid["tick"] + 200, 60, 0.2)
    after = server.state()
    counts["points_before_physics_kill"] = mid["points_total"]
    counts["points_after_restart"] = after["points_total"]
    counts["ticks"] = [before["tick"], mid["tick"], after["tick"]]
    lost = max(0, mid["points_total"] - after["points_total"])
    if after["points_total"] == mid["points_total"]:
        lost += int(sum(after["games_won"]) < sum(mid["games_won"]) or
                    (after["games_won"] == mid["games_won"] and sum(after["score"]) < sum(mid["score"])))
    # every slot full: the rest of the spectator places and both seats, then one spectator too many
    others = n - n // 2
    fill = run.add(launch(watch_spec(server.endpoint, others + 1, 2, "fill", records[1], duration=300,
                                     until_goodbye=True, join_timeout=30), "fill"))
    fill_ready = fill.expect(lambda o: o.get("event") == "ready", 60, "fill ready")
    keep_state = server.state()
    result["cpu_pct"] = meter.stop()
    t1 = time.monotonic()
    end = server.stop()
    keep_report = keep.expect(lambda o: o.get("event") == "report", 30, "report")
    fill_report = fill.expect(lambda o: o.get("event") == "report", 30, "report")
    clock = server.tick_clock()
    result["latency_ms"] = latency(latency_values(clock, server.dt, records[:2]))
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    told = keep_report["goodbyes"].get("shutdown", 0) + fill_report["goodbyes"].get("shutdown", 0)
    present = (keep_report["welcomed"] - keep_report["no_goodbye"] + fill_report["welcomed"])
    counts.update({"keep_rejoined": keep_report["rejoined"], "keep_welcomed": keep_report["welcomed"],
                   "fill_welcomed": fill_ready["welcomed"], "fill_rejected": fill_ready["rejected"],
                   "restarts": keep_state["restarts"], "goodbye_shutdown": told,
                   "clients_at_shutdown": keep_report["welcomed"] + fill_report["welcomed"],
                   "score_regressions": keep_report["regressions"]["score"] + fill_report["regressions"]["score"],
                   "tick_regressions": keep_report["regressions"]["tick"] + fill_report["regressions"]["tick"]})
    result["counts"] = counts
    result["lost_points"] = lost + counts["score_regressions"] + counts["tick_regressions"]
    check(result, counts["gateway_restarted"], "the gateway was not restarted")
    check(result, counts["physics_restarted"], "the physics worker was not restarted")
    check(result, keep_report["rejoined"] >= keep_report["welcomed"] > 0, f"{keep_report['welcomed']} watchers, "
                                                                         f"{keep_report['rejoined']} joined again")
    check(result, fill_ready["welcomed"] == others + 2 and fill_ready["rejected"] == {"full": 1},
           f"fill: {fill_ready['welcomed']} welcomed of {others} + 2, rejected {fill_ready['rejected']}")
    check(result, told == present, f"{present - told} of {present} clients without the shutdown goodbye")
    check(result, end.get("end") == "stopped", f"server ended {end.get('end')}")
    dead = {s.pid for s in (*doomed, players)}  # killed on purpose
    fds = {"keep": keep_report["fds_after"] - keep_report["fds_before"],
           "fill": fill_report["fds_after"] - fill_report["fds_before"]}
    return finish(result, run, server, shm_before, fds, expected_dead=dead, intended_restarts=2)
