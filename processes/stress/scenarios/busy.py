"""busy: a served cloth match on a machine kept busy, which must slow down, say so, and never break.

The default scene (the hanging cloth net in its own worker) is served with seat A held by a still
player (processes.stress.observer: it sends no input, only heartbeats, and keeps the books of its
session) and seat B by a bot player; spectators watch on the feed, a browser bridge shows the
match to a few WebSocket browsers, and `--hogs` CPU hogs (processes.stress.hogs) spin beside it
all from before the first serve until the end. After `--duration` s of play from the first serve
(or the match's end) the server is stopped, and every client must have been told why it ended.

Checks (the promises a served match makes on any machine):
- no worker raised and the server did not end in a server error (restarts within the budget
  are the supervisor doing its job: reported, not a problem);
- the still player's bat stayed at rest: its speed never above what the ball's touches can
  give it (an elastic touch of the ball, at most 2 m_ball |v_ball| / m_bat) while the idle brake
  holds it;
- no gap between the server's heartbeats on a session above a third of the welcome's timeout;
- the point events the still player got are the referee's points as the server logged them
  (in order, with the score after each; a point decided after its last snapshot may be missing);
- every client (still player, bot, spectators, bridge, browsers) was told goodbye with a reason.
Reported beside them: the realtime factor the server reached (snapshot.realtime_factor), snapshot
and net rates in wall time and how many ticks the net messages lag the newest snapshot, restarts.
"""
from __future__ import annotations

import asyncio
import os
import threading

from engine.physics.equipment import BALL_MASS
from engine.physics.scene import load_scene
from processes.network.wire import GoodbyeReason, Kind
from processes.stress.harness import Child, Run, bot, until
from processes.stress.hogs import CpuHogs
from processes.stress.probes import loadavg, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server
from processes.stress.swarm import launch, watch_spec

SCENE = "match"  # the default match: the cloth net in its own worker
SAFETY_S = 300.0  # every client's own bound beyond the run: a safety net, not a schedule
START_S = 300.0  # bound on each start-up step (a cold numba cache on a busy machine compiles for minutes)
ENDED = ("shutdown", "match_over")  # the goodbyes of a run that was stopped or whose match ended


async def _browser(url: str, seconds: float, seen: dict) -> None:
    """One WebSocket browser of the bridge: it counts snapshots and keeps the goodbye's reason."""
    from websockets.asyncio.client import connect

    async with connect(url.replace("http://", "ws://") + "ws", max_size=None, open_timeout=START_S) as ws:
        async def read():
            async for data in ws:
                if isinstance(data, bytes) and len(data) > 24 and data[6] == Kind.SNAPSHOT:
                    seen["snapshots"] = seen.get("snapshots", 0) + 1
                elif isinstance(data, bytes) and len(data) > 24 and data[6] == Kind.GOODBYE:
                    seen["goodbye"] = GoodbyeReason(data[24]).name.lower()

        try:
            await asyncio.wait_for(read(), timeout=seconds)
        except (asyncio.TimeoutError, TimeoutError):
            pass


def _browsers(url: str, n: int, seconds: float, seen: list[dict], errors: list) -> threading.Thread:
    """n browsers in a thread of their own until the bridge closes them (bounded by `seconds`)."""
    async def all_of():
        return await asyncio.gather(*(_browser(url, seconds, seen[k]) for k in range(n)), return_exceptions=True)

    thread = threading.Thread(target=lambda: errors.extend(e for e in asyncio.run(all_of()) if e is not None),
                              name="busy-browsers", daemon=True)
    thread.start()
    return thread


def _match_started(server: Server) -> bool:
    """Has the first serve been played (both seats held), or has the server already ended?"""
    tick = server.tick()
    return tick is None or tick > 0


def _still_bat_bound(still: dict) -> float:
    """m/s: the fastest the still bat may move, from the fastest ball the still player saw."""
    bat_mass = float(load_scene(SCENE).bats[0].mass)
    return 2.0 * BALL_MASS * still["ball_speed_max"] / bat_mass


def _points_agree(still: dict, logged: list[dict]) -> str | None:
    """None when the still player's point events are the server's logged points, else what differs."""
    got = [(p["winner"], p["score_after"]) for p in still["points"]]
    want = [(p["winner"], p["score_after"]) for p in logged]
    if got != want[:len(got)]:
        return f"point events {got[:5]}... differ from the server's points {want[:5]}..."
    last_seen = still["final"].get("tick", -1)
    missing = [p for p in logged[len(got):] if p["tick"] < last_seen]
    if missing:
        return f"{len(missing)} points logged before the still player's last snapshot have no event"
    return None


def scenario(args, run: Run) -> dict:
    result = base("busy")
    shm_before = shm_names()
    # every client's own bound: the wait for the first serve, the run, and the safety net after it
    seconds, bound = args.duration, START_S + args.duration + SAFETY_S
    hogs = CpuHogs(args.hogs)
    try:
        server = run.add(Server(run.tmp, players=2, scene=SCENE, snapshot_hz=args.hz, seconds=bound,
                                players_timeout=START_S))
        still = run.add(Child(["-m", "processes.stress.observer", server.endpoint, "--seconds", str(bound)], "still"))
        joined = still.expect(lambda o: "joined" in o or "error" in o, START_S, "the still player's seat")
        if "error" in joined:
            check(result, False, f"the still player was not seated: {joined['error']}")
            return finish(result, run, server, shm_before, {})
        swarm = run.add(launch(watch_spec(server.endpoint, args.busy_spectators, 0, "busy_", None, duration=bound,
                                          until_goodbye=True, join_timeout=START_S), "spectators"))
        ready = swarm.expect(lambda o: o.get("event") == "ready", START_S, "the spectators' ready line")
        bridge = run.add(Child(["-m", "processes.cli", "watch", server.endpoint, "--web", "127.0.0.1:0", "--json",
                                "--join-timeout", str(START_S), "--linger", "0", "--seconds", str(bound)], "bridge"))
        url = bridge.expect(lambda o: "url" in o, START_S, "the bridge's url")["url"]
        seen: list[dict] = [{} for _ in range(args.busy_browsers)]
        browser_errors: list = []
        browsers = _browsers(url, args.busy_browsers, bound, seen, browser_errors)
        hogs.start()  # from before the first serve: the bot's seat starts the match
        player = run.add(bot(server.endpoint, bound, args.seed))
        # The run's length counts from the first serve: the bot loads its kernels before it asks for
        # its seat (seconds on a busy machine), and a server stopped before it is seated would leave
        # it waiting for a welcome that never comes.
        started = until(lambda: _match_started(server), START_S, 0.2)
        check(result, started, f"the match did not start within {START_S:.0f} s: the bot was not seated")
        until(lambda: server.tick() is None, seconds)  # the run's length: --duration, or the match's end
        state = server.state() if server.tick() is not None else {}
        hogs.stop()
        end = server.stop()
        reports = {"still": still.expect(lambda o: "goodbye" in o, START_S, "the still player's report"),
                   "bot": player.expect(lambda o: "goodbye" in o, START_S, "the bot's summary"),
                   "spectators": swarm.expect(lambda o: o.get("event") == "report", START_S, "the spectators' report"),
                   "bridge": bridge.expect(lambda o: "end" in o, START_S, "the bridge's summary")}
        browsers.join(START_S)
    finally:
        hogs.stop()
    _judge(result, args, state, end, reports, ready, seen, browser_errors)
    return finish(result, run, server, shm_before, {})


def _judge(result: dict, args, state: dict, end: dict, reports: dict, ready: dict, seen: list[dict],
           browser_errors: list) -> None:
    still, spectators = reports["still"], reports["spectators"]
    workers = end.get("summary", {}).get("workers", {})  # a match that ended: the supervisor's own counts
    raised = state.get("raised") or {kind: w.get("raised", 0) for kind, w in workers.items()}
    restarts = state.get("restarts") or {kind: w.get("restarts", 0) for kind, w in workers.items()}
    check(result, end.get("end") in ("stopped", "match_over"), f"server ended {end.get('end')}")
    check(result, not any(raised.values()), f"a worker raised: {raised}")
    speed_bound = _still_bat_bound(still)
    check(result, still["bat_speed_max"] <= speed_bound + 1e-9,  # 1e-9 m/s: float64 rounding of the brake's steps
          f"the still bat moved at {still['bat_speed_max']:.4f} m/s, above the ball's {speed_bound:.4f} m/s")
    gap_bound = still["timeout_ms"] / 3000.0
    check(result, still["heartbeat_gap_max_s"] <= gap_bound,
          f"a heartbeat gap of {still['heartbeat_gap_max_s']} s, above a third of the timeout ({gap_bound:.3f} s)")
    disagreement = _points_agree(still, end.get("points", []))
    check(result, disagreement is None, disagreement or "")
    welcomed = spectators["welcomed"]
    told = sum(n for reason, n in spectators["goodbyes"].items() if reason in ENDED)
    endings = {"still": still["goodbye"], "bot": reports["bot"]["goodbye"], "bridge": reports["bridge"]["end"]}
    for who, reason in endings.items():
        check(result, reason in ENDED, f"the {who} ended with {reason}, not told why")
    check(result, welcomed == args.busy_spectators and told == welcomed,
          f"{told} of {welcomed} spectators told why it ended ({args.busy_spectators} asked)")
    browser_goodbyes = [s.get("goodbye") for s in seen]
    check(result, not browser_errors, f"{len(browser_errors)} browsers failed: {browser_errors[:3]}")
    check(result, all(g in ENDED for g in browser_goodbyes), f"browsers' goodbyes {browser_goodbyes}")
    result["counts"] = {
        "seconds": args.duration, "hogs": args.hogs, "loadavg": loadavg(), "cores": os.cpu_count(),
        "snapshot_hz_asked": args.hz, "realtime_factor": still["realtime_factor"],
        "snapshot_hz": still["snapshot_hz"], "spectator_rate_median_hz": spectators.get("rate_median"),
        "net_hz": still["net_hz"], "net_lag_ticks": still["net_lag_ticks"],
        "heartbeat_gap_max_s": still["heartbeat_gap_max_s"], "heartbeat_gap_bound_s": round(gap_bound, 3),
        "still_bat_speed_max": still["bat_speed_max"], "still_bat_speed_bound": speed_bound,
        "points": len(still["points"]), "restarts": restarts, "raised": raised,
        "spectators": welcomed, "spectators_rejected": sum(ready.get("rejected", {}).values()),
        "browsers": len(seen), "browser_snapshots_min": min((s.get("snapshots", 0) for s in seen), default=0),
        "endings": {**endings, "spectators": spectators["goodbyes"], "browsers": browser_goodbyes},
    }
