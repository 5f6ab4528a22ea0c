"""A browser that plays: its seat, its keys and aims, and only its own bat moves (processes.network.web.player)."""
import json
import threading

import numpy as np
import pytest

from processes.network import wire
from tests.helpers.browser import await_page, errors, get, page_state, serving
from tests.waits import DEADLINE_S, Deadline, wait_for

pytest.importorskip("websockets")


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
    pumping = serving(rig, stop)
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
            # The session polls the aim between its control ticks: wait for the prediction that shows it
            # (its y: the keys move the target along x only), not for a count of inputs sent.
            predicted = _texts(browser, lambda m: "predicted" in m and m["predicted"]["inputs_sent"] > 5
                               and m["predicted"]["aim"][1] != 0.0)
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
    pumping = serving(rig, stop)
    try:
        browser.get(url)
        await_page(browser, lambda s: s["connected"] and s["snapshots"] > 2)
        browser.find_element(By.CSS_SELECTOR, '#play button[data-seat="a"]').click()
        await_page(browser, lambda s: s["seat"] == "a" or s["rejected"])
        body = browser.find_element(By.TAG_NAME, "body")
        for key in "wwwwaaddr ":
            body.send_keys(key)
        state = await_page(browser, lambda s: s["keysSent"] >= 10 and s["predicted"] > 5)
        assert state["seat"] == "a" and state["camera"] == "a"  # the player's own view
        wait_for(lambda: any(bat == 0 and np.any(inputs != 0.0) for bat, _, _, inputs in list(rig.posted)),
                 "a push of bat A from the page's keys", seen=lambda: rig.posted[-3:])
        pushed = {bat for bat, _, _, inputs in list(rig.posted) if np.any(inputs != 0.0)}
        assert pushed == {0}  # the browser's bat, never the other
        assert errors(browser) == [] and page_state(browser)["errors"] == []
    finally:
        stop.set()
        pumping.join(DEADLINE_S)
