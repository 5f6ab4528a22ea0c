"""What the web bridge costs: the latency it adds, its CPU per forwarded message, and the page's
frame rate in headless Chromium.

A served match (`pingpong serve --players 0`, the AI on both bats, realtime) and its bridge
(`pingpong watch --web`) run as processes; this process is a direct spectator of the gateway
and N WebSocket browsers of the bridge at once. For every snapshot tick both receive, the
bridge's added latency is the WebSocket receipt minus the direct spectator's receipt (one clock,
one machine); the bridge's CPU is its process's user + system time over the run, divided by
the WebSocket messages it sent. With --fps, a headless Chromium (selenium, SwiftShader WebGL)
loads the page and counts requestAnimationFrame calls over 5 s.

`python -m bench.web --seconds 10 --browsers 50 [--fps] [--screenshot docs/web.png]` prints one JSON
object (the README's screenshot of the page is made so).
"""
from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np

from processes.network.client.client import Client
from processes.network.wire import Kind
from processes.stress.scenarios.web import browsers

CLK_TCK = os.sysconf("SC_CLK_TCK")


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime + stime


def _line(proc: subprocess.Popen, what: str) -> dict:
    line = proc.stdout.readline()
    if not line:
        raise RuntimeError(f"{what} printed nothing: {proc.stderr.read() if proc.stderr else ''}")
    return json.loads(line)


def _direct(endpoint: str, stop: threading.Event, seen: dict) -> None:
    client = Client(endpoint, "spectator", "bench")
    try:
        client.join(30)
        while not stop.is_set():
            client.heartbeat_if_due()
            message = client.recv(20)
            if message is not None and message.kind == Kind.SNAPSHOT:
                seen.setdefault(message.tick, time.monotonic())
    finally:
        client.leave()
        client.close()


def _fps(url: str, seconds: float = 5.0, screenshot: str = "") -> float:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--window-size=800,600"):
        options.add_argument(flag)
    options.binary_location = "/usr/bin/chromium"
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    try:
        driver.set_script_timeout(seconds + 30)
        driver.get(url)
        driver.execute_async_script("const done = arguments[arguments.length - 1];"
                                    "(function wait() { (window.__pingpong && window.__pingpong.frames > 10) ? done() :"
                                    " setTimeout(wait, 50); })();")
        fps = driver.execute_async_script(
            "const done = arguments[arguments.length - 1], seconds = arguments[0]; let n = 0;"
            "const t0 = performance.now(); (function count() { n += 1;"
            " if (performance.now() - t0 < seconds * 1000) requestAnimationFrame(count);"
            " else done(n / ((performance.now() - t0) / 1000)); })();", seconds)
        if screenshot:
            driver.save_screenshot(screenshot)
        return fps
    finally:
        driver.quit()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--browsers", type=int, default=50)
    parser.add_argument("--snapshot-hz", type=int, default=100)
    parser.add_argument("--fps", action="store_true", help="also the page's frame rate in headless Chromium")
    parser.add_argument("--screenshot", default="", metavar="PNG", help="with --fps: the page as it was, to this file")
    args = parser.parse_args(argv)
    cli = [sys.executable, "-m", "processes.cli"]
    server = subprocess.Popen(cli + ["serve", "--players", "0", "--ticks", "100000000", "--snapshot-hz",
                                     str(args.snapshot_hz), "--json"], stdout=subprocess.PIPE, text=True)
    bridge = None
    try:
        endpoint = _line(server, "serve")["listening"]
        bridge = subprocess.Popen(cli + ["watch", endpoint, "--web", "127.0.0.1:0", "--json"],
                                  stdout=subprocess.PIPE, text=True)
        url = _line(bridge, "watch")["url"]
        stop = threading.Event()
        direct: dict = {}
        spectator = threading.Thread(target=_direct, args=(endpoint, stop, direct), daemon=True)
        spectator.start()
        received: list[dict] = [dict() for _ in range(args.browsers)]
        cpu0, wall0 = _cpu_s(bridge.pid), time.monotonic()
        asyncio.run(browsers(url, args.browsers, args.seconds, received))
        seen = [per.get(Kind.SNAPSHOT, {}) for per in received]
        cpu, wall = _cpu_s(bridge.pid) - cpu0, time.monotonic() - wall0
        stop.set()
        spectator.join(10)
        added = np.array([t - direct[tick] for per in seen for tick, t in per.items() if tick in direct]) * 1000.0
        forwarded = sum(len(per) for per in seen)
        result = {
            "browsers": args.browsers, "seconds": round(wall, 2), "snapshot_hz": args.snapshot_hz,
            "snapshots_per_browser": round(forwarded / max(1, args.browsers), 1),
            "bridge_added_ms": {"p50": round(float(np.percentile(added, 50)), 3),
                                "p99": round(float(np.percentile(added, 99)), 3), "n": int(added.size)}
            if added.size else None,
            "bridge_cpu_pct": round(100.0 * cpu / wall, 1),
            "bridge_cpu_us_per_message": round(1e6 * cpu / max(1, forwarded), 2),
            "load_average": open("/proc/loadavg").read().split()[:3],
        }
        if args.fps:
            result["page_fps"] = round(_fps(url, screenshot=args.screenshot), 1)
        print(json.dumps(result))
    finally:
        for proc in (bridge, server):
            if proc is not None and proc.poll() is None:
                proc.send_signal(2)  # SIGINT: each says goodbye and cleans up
                try:
                    proc.wait(20)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(10)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
