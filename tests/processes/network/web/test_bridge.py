"""The web bridge: a gateway client forwarding the wire's bytes to browsers over a WebSocket.

The gateway runs in this process on 127.0.0.1 (a random port) with a clock the test sets, as in
test_gateway.py; the bridge runs its own threads; browsers are websockets' own client and
urllib. Every receive is bounded; every wait for an event by the suite's deadline (tests/waits.py). The page's decoder is run by node against the golden messages
of test_wire.py, where node is installed.
"""
import json
import re
import shutil
import subprocess
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from processes.network import wire
from processes.network.wire import protocol
from processes.network.server.feed import NetFeed
from processes.network.web import STATIC
from processes.network.web.bridge import WebBridge, parse_host_port
from processes.network.wire import Kind
from tests.processes.network.server.test_gateway import Rig
from tests.processes.network.wire.test_codec import GOLDEN
from tests.waits import DEADLINE_S, Deadline, wait_for

pytest.importorskip("websockets")


def _get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=DEADLINE_S) as reply:
            return reply.status, reply.headers.get("Content-Type", ""), reply.read()
    except urllib.error.HTTPError as err:
        return err.code, "", b""


@pytest.fixture
def bridged(zctx):
    """A gateway with a snapshot to serve, and a bridge joined to it as a spectator."""
    rig = Rig(zctx)
    bridge = WebBridge(rig.gateway.endpoint, "127.0.0.1:0")

    def pump_join():
        deadline = Deadline()
        while not deadline.expired():
            rig.step()
            if rig.gateway.counts["spectators_joined"]:
                return

    pumping = threading.Thread(target=pump_join, daemon=True)  # the gateway answers while start() waits
    pumping.start()
    url = bridge.start(DEADLINE_S)
    pumping.join(DEADLINE_S)
    yield rig, bridge, url
    bridge.stop()
    rig.close()


def test_the_page_and_its_scripts_load_from_the_bridge_and_nothing_from_elsewhere(bridged):
    _, _, url = bridged
    status, kind, page = _get(url)
    assert status == 200 and kind.startswith("text/html")
    for script in ("app.js", "decoder.js", "vendor/three.module.min.js"):
        status, kind, body = _get(url + script)
        assert status == 200 and kind.startswith("text/javascript") and body, script
    status, _, body = _get(url + "protocol.json")
    assert status == 200 and json.loads(body) == json.loads(json.dumps(protocol.layout_json()))
    assert _get(url + "nothing-here")[0] == 404
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
        tick, clock = 0, _wall_clock(rig)
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


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed (apt-get install nodejs)")
def test_the_pages_decoder_reads_every_golden_message_as_python_does(tmp_path):
    script = tmp_path / "decode.mjs"
    script.write_text(f"""import {{ Decoder }} from {json.dumps((STATIC / 'decoder.js').as_uri())};
import {{ readFileSync }} from "fs";
const input = JSON.parse(readFileSync(0, "utf8"));
const decoder = new Decoder(input.protocol);
const out = {{}};
for (const [name, hex] of Object.entries(input.golden)) out[name] = decoder.decode(Uint8Array.from(Buffer.from(hex, "hex")));
console.log(JSON.stringify(out));
""")
    feed = json.dumps({"protocol": protocol.layout_json(), "golden": {k: v.hex() for k, v in GOLDEN.items()}})
    done = subprocess.run(["node", str(script)], input=feed, capture_output=True, text=True, timeout=DEADLINE_S)
    assert done.returncode == 0, done.stderr
    decoded = json.loads(done.stdout)
    for name, data in GOLDEN.items():
        message = wire.decode(data)
        js = decoded[name]
        assert (js["kind"], js["seq"], js["tick"], js["flags"]) == (message.kind.name.lower(), message.seq,
                                                                     message.tick, message.flags), name
        for field, value in message.fields.items():
            expected = value.hex() if isinstance(value, bytes) else (
                value.tolist() if hasattr(value, "tolist") else int(value) if isinstance(value, int) else value)
            assert js[field] == expected, (name, field)  # floats bit for bit: JSON round-trips float64


# --- in a real browser: headless Chromium through selenium --------------------------------------
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
INSTALL = "apt-get install chromium chromium-driver (as root) and pip install selenium; `make test` does both"


@pytest.fixture
def browser():
    """Headless Chromium with WebGL on SwiftShader (no GPU), its console kept; quit at the end."""
    webdriver = pytest.importorskip("selenium.webdriver", reason=f"selenium is not installed: {INSTALL}")
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip(f"no chromium or chromedriver: {INSTALL}")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--window-size=800,600", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.binary_location = CHROMIUM
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(DEADLINE_S)
    driver.set_script_timeout(DEADLINE_S)
    yield driver
    driver.quit()


def _page_state(driver):
    return driver.execute_script("return window.__pingpong || null")


def _await_page(driver, check):
    """The page's state once check(state) holds: polled in the browser every 0.1 s, within the deadline."""
    deadline, state = Deadline(), None
    while not deadline.expired():
        state = driver.execute_async_script(
            "const done = arguments[arguments.length - 1]; setTimeout(() => done(window.__pingpong || null), 100);")
        if state is not None and check(state):
            return state
    raise AssertionError(f"the page never got there within {DEADLINE_S:.0f} s: {state}")


def _screenshot(driver):
    import io

    from matplotlib import image

    return np.asarray(image.imread(io.BytesIO(driver.get_screenshot_as_png()), format="png"))[..., :3]


def _errors(driver):
    return [entry for entry in driver.get_log("browser") if entry["level"] == "SEVERE"]


def _drawn_at(driver, ball_pos):
    """The page's state once it has drawn frames with the ball held at ball_pos: the frame
    counter past the first frame that drew it there, so the picture on screen is one of them."""
    state = _await_page(driver, lambda s: s["ball"] is not None and np.allclose(s["ball"], ball_pos, rtol=0, atol=1e-9))
    return _await_page(driver, lambda s: s["frames"] >= state["frames"] + 2)


def test_the_live_page_draws_the_match_and_shows_the_servers_score(bridged, browser):
    rig, bridge, url = bridged
    rig.record["rally"]["score"] = (3, 5)
    rig.record["rally"]["games_won"] = (1, 0)
    rig.record["rally"]["server"] = 1
    stop = threading.Event()
    held = [(-1.0, 0.1, 0.25)]  # the ball stands over A's half, then over B's
    pumping = _serving(rig, stop, held)
    try:
        browser.get(url)
        state = _await_page(browser, lambda s: s["connected"] and s["frames"] > 5 and s["snapshots"] > 5)
        assert state["score"] == [3, 5] and state["games"] == [1, 0] and state["server"] == 1  # the server's
        _drawn_at(browser, held[-1])
        first = _screenshot(browser)
        assert first.std() > 0.05  # a scene, not a blank canvas
        held.append((1.0, 0.1, 0.25))
        _drawn_at(browser, held[-1])
        second = _screenshot(browser)
        assert np.abs(second - first).max() > 0.1  # the ball moved between the two pictures
        assert _errors(browser) == [] and _page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
    assert bridge.counts["browsers"] == 1


def test_the_live_page_draws_a_cloth_nets_knots_in_place_of_the_panel(bridged, browser):
    """The gateway's net messages (an 85 x 8 net bulging and moving, two messages a state) reach
    the page through the bridge, which draws the mesh from them, every knot of it."""
    rig, bridge, url = bridged
    cols, rows, width, height = 85, 8, 1.83, 0.1525
    rig.gateway.net = NetFeed((cols, rows, width, height), rig.gateway.config.snapshot_hz)  # as a cloth run's
    rest = wire.net_rest(cols, rows, width, height)
    stop = threading.Event()

    def serve():
        tick, clock = 0, _wall_clock(rig)
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
        state = _await_page(browser, lambda s: s["connected"] and s["netShown"] >= 4 and s["frames"] > 5)
        assert state["netKnots"] == cols * rows and state["nets"] >= state["netShown"]
        assert browser.execute_script("return window.__pingpong.netTick") > 0
        assert _errors(browser) == [] and _page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
    assert bridge.counts["nets"] >= 4


def test_the_replay_page_plays_offline_from_one_file(browser, tmp_path):
    from engine.dtypes import physics_snapshot_dtype
    from engine.rules import REASONS, Reason
    from processes.network.web.replay import replay_page

    welcome = wire.encode(Kind.WELCOME, tick=0, slot=wire.Slot.NONE, best_of=1, snapshot_hz=100, heartbeat_ms=500,
                          timeout_ms=5000, dt=0.001, token=bytes(16), scene="match", name_a="Ada", name_b="Bo",
                          feed_port=0)
    record = np.zeros(1, physics_snapshot_dtype(2))[0]
    record["bats"]["quat"] = (1.0, 0.0, 0.0, 0.0)
    record["rally"]["winner"] = -1
    messages = [welcome]
    for i in range(300):  # 3 s of play at 100 snapshots a second
        record["world"]["tick"] = 10 * i
        record["ball"]["pos"] = (-1.2 + 0.008 * i, 0.0, 0.2)
        messages.append(wire.snapshot_from_physics(record, seq=i + 1))
    messages.insert(150, wire.encode(Kind.EVENT, tick=1480, event=wire.EventKind.POINT, winner=1,
                                     reason=REASONS.index(Reason.OUT_LONG), game=0, score=(0, 1), games_won=(0, 0),
                                     shots=3, rally=1))
    page = tmp_path / "replay.html"
    page.write_text(replay_page(messages, "a test"), encoding="utf-8")
    assert "http://" not in page.read_text() and "https://" not in page.read_text()  # nothing to fetch
    browser.get(page.as_uri())
    state = _await_page(browser, lambda s: s["events"] == 1 and s["frames"] > 10)
    assert state["lastEvent"]["reason"] == "out_long" and state["lastEvent"]["winner"] == 1
    assert _screenshot(browser).std() > 0.05
    assert _errors(browser) == [] and state["errors"] == []


def _wall_clock(rig):
    """A function that sets the rig's clock to where the wall clock says, from now on.

    The bridge's client gives the gateway up when its session is silent for the welcome's timeout
    of wall-clock time, and the gateway heartbeats by its own clock: a serving loop that stepped
    that clock by 1 ms a turn ran it slower than the wall on a busy machine, and the bridge gave
    the gateway up before its first heartbeat."""
    base, start = rig.clock.now, time.monotonic()

    def advance():
        rig.clock.now = base + (time.monotonic() - start)

    return advance


def _serving(rig, stop, held=None):
    """The gateway serves its record until `stop` (a thread): a ball flying along the table, or
    standing where the last entry of the list `held` says."""
    def serve():
        tick, clock = 0, _wall_clock(rig)
        while not stop.is_set():
            tick += 1
            rig.record["world"]["tick"] = tick
            rig.record["ball"]["pos"] = held[-1] if held else (-1.2 + 2.4 * ((tick // 10) % 100) / 100.0, 0.1, 0.25)
            clock()
            rig.gateway.poll(1)
            rig.gateway.service(rig.record)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return thread


def _texts(browser, check):
    """JSON text messages from the bridge until check(message) holds (binary ones skipped; within the deadline)."""
    deadline = Deadline()
    while not deadline.expired():
        try:
            data = browser.recv(timeout=0.05)
        except TimeoutError:
            continue
        if isinstance(data, str) and check(json.loads(data)):
            return json.loads(data)
    raise AssertionError(f"no such message from the bridge within {DEADLINE_S:.0f} s")


def test_a_browser_plays_its_own_seat_and_moves_only_its_own_bat(bridged):
    from websockets.sync.client import connect

    rig, bridge, url = bridged
    stop = threading.Event()
    pumping = _serving(rig, stop)
    try:
        with connect(url.replace("http://", "ws://") + "ws", open_timeout=DEADLINE_S) as watcher, \
                connect(url.replace("http://", "ws://") + "ws", open_timeout=DEADLINE_S) as browser:
            watcher.send(json.dumps({"key": "up"}))  # a page that plays no seat controls nothing
            browser.send(json.dumps({"play": "a"}))
            assert _texts(browser, lambda m: "seat" in m or "rejected" in m)["seat"] == "a"
            for _ in range(5):
                browser.send(json.dumps({"key": "up"}))  # the keys `join` uses, towards the net
            browser.send(json.dumps({"aim": [-1.6, 0.3, 0.2]}))  # the pointer's point
            browser.send(json.dumps({"aim": [99.0, 0.0, 0.0]}))  # beyond the wire's range: ignored
            predicted = _texts(browser, lambda m: "predicted" in m and m["predicted"]["inputs_sent"] > 5)
            assert len(predicted["predicted"]["bat_pos"]) == 3 and predicted["predicted"]["aim"][1] == pytest.approx(0.3)
            deadline = Deadline()
            while not deadline.expired():
                if any(bat == 0 and np.any(inputs != 0.0) for bat, _, _, inputs in list(rig.posted)):
                    break
                try:
                    browser.recv(timeout=0.05)  # (read what the bridge sends meanwhile)
                except TimeoutError:
                    pass
            pushed = [(bat, inputs) for bat, _, _, inputs in list(rig.posted) if np.any(inputs != 0.0)]
            assert pushed and {bat for bat, _ in pushed} == {0}  # bat A only: the other is out of reach
            assert rig.gateway.counts.get("refused.other_bat", 0) == 0
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
    assert bridge.counts["players"] == 1 and bridge.counts["ignored_from_browser"] >= 2


def test_in_the_browser_a_player_takes_seat_a_and_its_keys_push_only_bat_a(bridged, browser):
    from selenium.webdriver.common.by import By

    rig, bridge, url = bridged
    stop = threading.Event()
    pumping = _serving(rig, stop)
    try:
        browser.get(url)
        _await_page(browser, lambda s: s["connected"] and s["snapshots"] > 2)
        browser.find_element(By.CSS_SELECTOR, '#play button[data-seat="a"]').click()
        _await_page(browser, lambda s: s["seat"] == "a" or s["rejected"])
        body = browser.find_element(By.TAG_NAME, "body")
        for key in "wwwwaaddr ":
            body.send_keys(key)
        state = _await_page(browser, lambda s: s["keysSent"] >= 10 and s["predicted"] > 5)
        assert state["seat"] == "a" and state["camera"] == "a"  # the player's own view
        wait_for(lambda: any(bat == 0 and np.any(inputs != 0.0) for bat, _, _, inputs in list(rig.posted)),
                 "a push of bat A from the page's keys", seen=lambda: rig.posted[-3:])
        pushed = {bat for bat, _, _, inputs in list(rig.posted) if np.any(inputs != 0.0)}
        assert pushed == {0}  # the browser's bat, never the other
        assert _errors(browser) == [] and _page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
