"""The web bridge: a gateway client forwarding the wire's bytes to browsers over a WebSocket, and
the live page it serves (processes.network.web.bridge).

The gateway runs in this process on 127.0.0.1 (a random port) with a clock the test sets
(tests.helpers.gateway.Rig); the bridge runs its own threads; browsers are websockets' own client,
urllib and a headless Chromium. Every receive is bounded; every wait for an event by the suite's
deadline (tests/waits.py).
"""
import json
import re
import threading
import urllib.error
import urllib.request

import numpy as np
import pytest

from processes.network import wire
from processes.network.wire import protocol
from processes.network.server.feed import NetFeed
from processes.network.web import STATIC
from processes.network.web.bridge import parse_host_port
from processes.network.wire import Kind
from tests.helpers.browser import await_page, drawn_at, errors, get, page_state, screenshot, serving, wall_clock
from tests.helpers.gateway import Rig
from tests.waits import DEADLINE_S, Deadline

pytest.importorskip("websockets")


def test_the_page_and_its_scripts_load_from_the_bridge_and_nothing_from_elsewhere(bridged):
    _, _, url = bridged
    status, kind, page = get(url)
    assert status == 200 and kind.startswith("text/html")
    for script in ("app.js", "decoder.js", "vendor/three.module.min.js"):
        status, kind, body = get(url + script)
        assert status == 200 and kind.startswith("text/javascript") and body, script
    status, _, body = get(url + "protocol.json")
    assert status == 200 and json.loads(body) == json.loads(json.dumps(protocol.layout_json()))
    assert get(url + "nothing-here")[0] == 404
    for name in ("index.html", "app.js", "decoder.js"):  # no CDN: every import and src is relative
        text = (STATIC / name).read_text()
        assert not re.search(r"""(src|href|from)\s*=?\s*["']https?://""", text), name
    assert (STATIC / "vendor" / "three.LICENSE").read_text().startswith("The MIT License")


def test_a_browser_gets_the_welcome_then_the_feeds_own_snapshot_bytes(bridged):
    from websockets.sync.client import connect

    rig, bridge, url = bridged
    watcher = rig.client(role="spectator")
    rig.join(watcher)
    with connect(url.replace("http://", "ws://") + "ws", open_timeout=DEADLINE_S) as browser:
        first = wire.decode(browser.recv(timeout=DEADLINE_S))
        assert first.kind == Kind.WELCOME and first["scene"] == "match_rigid"
        forwarded = None
        tick, clock = 0, wall_clock(rig)
        deadline = Deadline()
        while not deadline.expired():  # serve ticks until a snapshot reaches the browser
            tick += 1
            rig.record["world"]["tick"] = tick
            clock()
            rig.gateway.poll(1)
            rig.gateway.service(rig.record)
            try:
                data = browser.recv(timeout=0.01)
            except TimeoutError:
                continue
            if wire.decode(data).kind == Kind.SNAPSHOT:
                forwarded = data
                break
        assert forwarded is not None, "no snapshot reached the browser"
        message = wire.decode(forwarded)
        deadline = Deadline()
        while not deadline.expired():  # the same tick as a direct spectator of the gateway got it
            direct = watcher.recv(10)
            if direct is not None and direct.kind == Kind.SNAPSHOT and direct.tick == message.tick:
                break
        assert forwarded == wire.encode(direct.kind, seq=direct.seq, tick=direct.tick, flags=direct.flags,
                                        **direct.fields)
        browser.send(b"anything")  # a browser controls nothing: ignored, counted
    assert bridge.counts["browsers"] == 1 and bridge.counts["forwarded"] >= 1


def test_web_addresses_are_host_and_port():
    assert parse_host_port("127.0.0.1:0") == ("127.0.0.1", 0)
    with pytest.raises(ValueError):
        parse_host_port("8080")


def test_the_live_page_draws_the_match_and_shows_the_servers_score(bridged, browser):
    rig, bridge, url = bridged
    rig.record["rally"]["score"] = (3, 5)
    rig.record["rally"]["games_won"] = (1, 0)
    rig.record["rally"]["server"] = 1
    stop = threading.Event()
    held = [(-1.0, 0.1, 0.25)]  # the ball stands over A's half, then over B's
    pumping = serving(rig, stop, held)
    try:
        browser.get(url)
        state = await_page(browser, lambda s: s["connected"] and s["frames"] > 5 and s["snapshots"] > 5)
        assert state["score"] == [3, 5] and state["games"] == [1, 0] and state["server"] == 1  # the server's
        drawn_at(browser, held[-1])
        first = screenshot(browser)
        assert first.std() > 0.05  # a scene, not a blank canvas
        held.append((1.0, 0.1, 0.25))
        drawn_at(browser, held[-1])
        second = screenshot(browser)
        assert np.abs(second - first).max() > 0.1  # the ball moved between the two pictures
        assert errors(browser) == [] and page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
    assert bridge.counts["browsers"] == 1


def test_the_live_page_draws_a_cloth_nets_knots_in_place_of_the_panel(bridged, browser):
    """The gateway's net messages (an 85 x 8 net bulging and moving, two messages a state) reach
    the page through the bridge, which draws the mesh from them, every knot of it."""
    rig, bridge, url = bridged
    cols, rows, width, height = 85, 8, 1.83, 0.1525
    rig.gateway.net = NetFeed((cols, rows, width, height), rig.gateway.config.snapshot_hz, rig.gateway.dt)
    rest = wire.net_rest(cols, rows, width, height)
    stop = threading.Event()

    def serve():
        tick, clock = 0, wall_clock(rig)
        while not stop.is_set():
            tick += 1
            rig.record["world"]["tick"] = tick
            clock()
            rig.gateway.poll(1)
            rig.gateway.service(rig.record)
            if rig.gateway.net_due():
                knots = rest.copy()
                knots[:, 0] = 0.03 * np.sin(np.pi * (rest[:, 1] / width + 0.5)) * np.sin(tick * 0.01)
                rig.gateway.service_net(tick, False, knots)

    pumping = threading.Thread(target=serve, daemon=True)
    pumping.start()
    try:
        browser.get(url)
        state = await_page(browser, lambda s: s["connected"] and s["netShown"] >= 4 and s["frames"] > 5)
        assert state["netKnots"] == cols * rows and state["nets"] >= state["netShown"]
        assert browser.execute_script("return window.__pingpong.netTick") > 0
        assert errors(browser) == [] and page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
    assert bridge.counts["nets"] >= 4
