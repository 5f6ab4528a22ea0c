"""The page in a test: its files over HTTP, its state read in the browser, its picture; a rig
serving its record on the wall clock, as a page expects."""
import threading
import time
import urllib.error
import urllib.request

import numpy as np

from tests.waits import DEADLINE_S, Deadline


def get(url: str) -> tuple[int, str, bytes]:
    """(status, content type, body) of an HTTP GET of `url`, within the deadline."""
    try:
        with urllib.request.urlopen(url, timeout=DEADLINE_S) as reply:
            return reply.status, reply.headers.get("Content-Type", ""), reply.read()
    except urllib.error.HTTPError as err:
        return err.code, "", b""


def page_state(driver):
    """The page's own report of its state (window.__pingpong), or None before it has one."""
    return driver.execute_script("return window.__pingpong || null")


def await_page(driver, check):
    """The page's state once check(state) holds: polled in the browser every 0.1 s, within the deadline."""
    deadline, state = Deadline(), None
    while not deadline.expired():
        state = driver.execute_async_script(
            "const done = arguments[arguments.length - 1]; setTimeout(() => done(window.__pingpong || null), 100);")
        if state is not None and check(state):
            return state
    raise AssertionError(f"the page never got there within {DEADLINE_S:.0f} s: {state}")


def screenshot(driver):
    """The page as an (height, width, 3) RGB array."""
    import io

    from matplotlib import image

    return np.asarray(image.imread(io.BytesIO(driver.get_screenshot_as_png()), format="png"))[..., :3]


def errors(driver):
    """The browser console's SEVERE entries."""
    return [entry for entry in driver.get_log("browser") if entry["level"] == "SEVERE"]


def drawn_at(driver, ball_pos):
    """The page's state once it has drawn frames with the ball held at ball_pos: the frame
    counter past the first frame that drew it there, so the picture on screen is one of them."""
    state = await_page(driver, lambda s: s["ball"] is not None and np.allclose(s["ball"], ball_pos, rtol=0, atol=1e-9))
    return await_page(driver, lambda s: s["frames"] >= state["frames"] + 2)


def wall_clock(rig):
    """A function that sets the rig's clock to where the wall clock says, from now on.

    The bridge's client gives the gateway up when its session is silent for the welcome's timeout
    of wall-clock time, and the gateway heartbeats by its own clock: a serving loop that stepped
    that clock by 1 ms a turn ran it slower than the wall on a busy machine, and the bridge gave
    the gateway up before its first heartbeat."""
    base, start = rig.clock.now, time.monotonic()

    def advance():
        rig.clock.now = base + (time.monotonic() - start)

    return advance


def serving(rig, stop, held=None):
    """The gateway serves its record until `stop` (a thread): a ball flying along the table, or
    standing where the last entry of the list `held` says."""
    def serve():
        tick, clock = 0, wall_clock(rig)
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
