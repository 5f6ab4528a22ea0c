"""web: N WebSocket browsers on one web bridge of a served match (AI against AI).

The bridge (`pingpong watch ADDRESS --web`) is one spectator of the gateway that forwards every
wire message to each browser; here the browsers are asyncio WebSocket clients (the `websockets`
library, as bench/web.py's are) that count the snapshots they get for `duration` seconds. The
result: snapshots per browser against the ones the gateway sent, and the bridge's CPU, in all and
per message forwarded. A browser that got no snapshot at all is a problem.
"""
from __future__ import annotations

import asyncio
import sys
import time

import numpy as np

from processes.network.wire import Kind
from processes.stress.harness import Child, Run
from processes.stress.probes import CpuMeter, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server


async def _browser(url: str, seconds: float, seen: dict) -> None:
    from websockets.asyncio.client import connect

    async with connect(url.replace("http://", "ws://") + "ws", max_size=None, open_timeout=60) as ws:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                data = await asyncio.wait_for(ws.recv(), timeout=max(0.01, deadline - time.monotonic()))
            except (asyncio.TimeoutError, TimeoutError):
                break
            if isinstance(data, bytes) and len(data) > 24 and data[6] in (Kind.SNAPSHOT, Kind.NET):
                tick = int.from_bytes(data[16:24], "little", signed=True)
                seen.setdefault(data[6], {}).setdefault(tick, time.monotonic())


async def browsers(url: str, n: int, seconds: float, seen: list[dict]) -> list[BaseException | None]:
    """n WebSocket browsers of the bridge at `url` for `seconds`; seen[k]: {kind: {tick: receipt s}}
    of browser k (snapshots and net messages, CLOCK_MONOTONIC). Returns each browser's error or None."""
    return await asyncio.gather(*(_browser(url, seconds, seen[k]) for k in range(n)), return_exceptions=True)


def scenario(args, run: Run) -> dict:
    result = base("web")
    shm_before = shm_names()
    n, seconds = args.browsers, args.duration
    server = run.add(Server(run.tmp, players=0, snapshot_hz=args.hz, seconds=seconds + 120))
    bridge = run.add(Child(["-m", "processes.cli", "watch", server.endpoint, "--web", "127.0.0.1:0", "--json",
                            "--join-timeout", "60"], "bridge"))
    url = bridge.expect(lambda o: "url" in o, 90, "the bridge's url")["url"]
    meter = CpuMeter()
    meter.start({"bridge": bridge.pid, **server.all_pids()})
    seen: list[dict] = [{} for _ in range(n)]
    t0 = time.monotonic()
    errors = asyncio.run(browsers(url, n, seconds, seen))
    wall = time.monotonic() - t0
    result["cpu_pct"] = meter.stop()
    sent = server.gateway_stats().get("snapshots_published", 0)
    bridge.proc.send_signal(2)  # SIGINT: it says goodbye to the gateway and closes every browser
    bridge.wait(20)
    end = server.stop()
    snapshots = np.array([len(s.get(Kind.SNAPSHOT, {})) for s in seen])
    nets = np.array([len(s.get(Kind.NET, {})) for s in seen])
    failed = [e for e in errors if e is not None]
    bridge_pct = result["cpu_pct"].get("bridge")
    forwarded = int(snapshots.sum() + nets.sum())
    result["counts"] = {
        "browsers": n, "seconds": seconds, "snapshot_hz": args.hz, "browser_errors": len(failed),
        "snapshots_per_browser_min": int(snapshots.min()) if n else 0,
        "snapshots_per_browser_p50": float(np.median(snapshots)) if n else 0,
        "net_states_per_browser_p50": float(np.median(nets)) if n else 0,
        "gateway_snapshots_published": sent,
        "bridge_cpu_us_per_message": round(1e4 * bridge_pct * wall / forwarded, 2)
        if bridge_pct is not None and forwarded else None,
    }
    check(result, not failed, f"{len(failed)} browsers failed: {failed[:3]}")
    check(result, n == 0 or snapshots.min() > 0, "a browser got no snapshot")
    check(result, end.get("end") in ("stopped", "match_over"), f"server ended {end.get('end')}")
    return finish(result, run, server, shm_before, {})
