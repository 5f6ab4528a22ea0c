"""Keyboard play: key parsing from a real pseudo-terminal, the target and the arm's forces, a
keyboard session against an in-process gateway, and `pingpong join --as player` on a pty.

The gateway runs in a thread of this process (its socket is used by that thread only), pumped
until the test stops it; every wait is bounded.
"""
import os
import select
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.physics.world import build_model, initial_state
from processes.network.client.client import Client
from processes.network.client.session import SessionOptions, run_session
from processes.network.server.config import GatewayConfig
from processes.network.server.gateway import Gateway
from processes.network.client.keyboard import STEP_M, STROKE_M, IterableKeys, KeyboardPilot, TerminalKeys, parse_keys, top_view
from processes.network.client.prediction import Predictor
from processes.network.wire import Slot
from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[4]
PRO_MAX_FORCE_N = 120.0  # engine.play.ai.SKILLS["pro"].max_force_n


def test_parse_keys_reads_letters_arrows_and_keeps_a_cut_escape():
    assert parse_keys(b"wasd rfq") == (["up", "left", "down", "right", "stroke", "raise", "lower", "quit"], b"")
    assert parse_keys(b"\x1b[A\x1b[B\x1bOC\x1b[D") == (["up", "down", "right", "left"], b"")
    assert parse_keys(b"W\x1b[") == (["up"], b"\x1b[")  # the arrow's last byte comes in the next read
    assert parse_keys(b"\x1b[Zx\x1b") == ([], b"\x1b")  # unknown sequence and letter skipped


def test_terminal_keys_from_a_pseudo_terminal_in_cbreak_mode():
    master, slave = os.openpty()
    try:
        with TerminalKeys(slave) as keys:
            assert keys.poll(0.0) == []
            os.write(master, b"w\x1b[")  # no Enter: cbreak mode hands every byte over at once
            assert keys.poll(5.0) == ["up"]
            os.write(master, b"Bq")
            assert keys.poll(5.0) == ["down", "quit"]
    finally:
        os.close(master)
        os.close(slave)


def test_keys_move_the_target_in_the_players_own_frame_within_reach():
    model = build_model(load_scene("match_rigid"))
    a, b = KeyboardPilot(model, Slot.A), KeyboardPilot(model, Slot.B)
    start_a, start_b = a.target.copy(), b.target.copy()
    for key in ("up", "left", "raise"):
        a.press(key, 0.0)
        b.press(key, 0.0)
    # forward is towards the net (+x for A, -x for B); left of a player facing +x is +y
    np.testing.assert_allclose(a.target - start_a, [STEP_M, STEP_M, STEP_M], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.target - start_b, [-STEP_M, -STEP_M, STEP_M], rtol=0, atol=1e-12)
    a.press("stroke", 1.0)
    assert a.aim(1.05)[0] == pytest.approx(a.target[0] + STROKE_M, abs=1e-12) and a.aim(2.0)[0] == a.target[0]
    for _ in range(200):
        a.press("up", 0.0)
    assert a.target[0] == pytest.approx(-1.37 + 0.5, abs=1e-9)  # reach: 0.5 m over its end line, no further
    with pytest.raises(ValueError, match="slot must be A or B"):
        KeyboardPilot(model, Slot.NONE)
    with pytest.raises(ValueError, match="unknown keys"):
        IterableKeys([["jump"]]).poll()
    # the force follows the target at every call (not only the first): PD towards the aim
    bat = initial_state(load_scene("match_rigid")).bats[0]
    a.target = np.array([-1.77, 0.0, 0.15])
    assert np.abs(a.control(5.0, bat)[0:3]).max() < 1e-9  # the bat rests where it should: no force
    a.press("up", 5.0)
    assert a.control(5.0, bat)[0] > 0.0  # target ahead: pushed towards the net
    a.press("down", 5.0)
    a.press("down", 5.0)
    assert a.control(5.0, bat)[0] < 0.0  # target behind: pulled back
    np.testing.assert_allclose(np.linalg.norm(a.control(5.0, bat)[0:3]), 900.0 * 0.05 * model.bat_mass[0],
                               rtol=1e-12)  # m kp |error| (kp = 30^2 /s^2, 5 cm), under the 120 N limit
    rows = top_view((0.0, 0.0, 0.1), np.array([[-1.77, 0.0, 0.1], [1.77, 0.0, 0.1]]), a.target)
    assert len(rows) == 15 and "A" in "".join(rows) and "B" in "".join(rows) and "o" in "".join(rows)


class GatewayThread:
    """A Gateway on 127.0.0.1 serving a still record whose tick follows the wall clock."""

    def __init__(self, zctx, scene):
        self.posted = []
        self.gateway = Gateway(zctx, GatewayConfig(bind="tcp://127.0.0.1:0", snapshot_hz=100, heartbeat_s=0.2,
                                                   timeout_s=5.0), scene=scene, remote_slots=(Slot.A,),
                               post_input=self._post)
        self.record = initial_state(scene).record[0].copy()
        self.record["rally"]["winner"] = -1
        self.dt = scene.dt
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _post(self, bat, seq, tick, inputs):
        self.posted.append((bat, seq, tick, np.array(inputs)))
        return True

    def _run(self):
        started = time.monotonic()
        while not self.stop.is_set() and time.monotonic() - started < DEADLINE_S:
            self.gateway.poll(1)
            self.record["world"]["tick"] = int((time.monotonic() - started) / self.dt)
            self.gateway.service(self.record)

    def wait_for(self, check, seconds=DEADLINE_S):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if check():
                return True
            self.stop.wait(0.05)  # polling another thread's progress, bounded
        return False

    def close(self):
        self.stop.set()
        self.thread.join(DEADLINE_S)
        self.gateway.close()


def test_a_keyboard_session_sends_the_arms_forces_towards_the_target(zctx):
    scene = load_scene("match_rigid")
    # Built before joining: on a cold numba cache its kernels compile for longer than the welcome's
    # timeout, and a client silent meanwhile takes the server for lost.
    predictor = Predictor(scene, Slot.A)
    served = GatewayThread(zctx, scene)
    client = Client(served.gateway.endpoint, "player", "keys", zctx=zctx)
    try:
        welcome = client.join(DEADLINE_S)
        assert client.slot == Slot.A
        pilot = KeyboardPilot(predictor.model, client.slot)
        keys = IterableKeys([["up"] * 4] + [[]] * 150 + ["quit"])
        summary = run_session(client, welcome, SessionOptions(pilot=pilot, keys=keys, predictor=predictor,
                                                              seconds=DEADLINE_S))
        assert summary["goodbye"] == "quit" and summary["snapshots"] > 0 and summary["inputs_sent"] > 0
        np.testing.assert_allclose(pilot.target, [-1.77 + 4 * STEP_M, 0.0, 0.15], rtol=0, atol=1e-12)
        assert served.wait_for(lambda: served.gateway.counts["quits"] == 1)
        forces = np.array([p[3] for p in served.posted])
        # ours only: the gateway forwards inputs (the physics lets go of an absent arm's last one),
        # each one posted or, arrived together with a newer one, replaced by it
        counts = served.gateway.counts
        assert len(forces) + counts["inputs_coalesced"] == summary["inputs_sent"], (summary, dict(counts))
        # the bat starts at rest 20 cm behind the target: the arm pushes it towards the net, within its limit
        assert forces[0][0] > 0.0 and abs(forces[0][1]) < 1e-9
        assert np.linalg.norm(forces[:, 0:3], axis=1).max() <= PRO_MAX_FORCE_N + 1e-9
        assert 0 < summary["prediction"]["snapshots"] == summary["snapshots_acted_on"] <= summary["snapshots"]
    finally:
        client.close()
        served.close()


def test_pingpong_join_plays_from_the_keyboard_on_a_terminal(zctx):
    """The real command on a pseudo-terminal: it draws the table, takes keys, leaves on q."""
    served = GatewayThread(zctx, load_scene("match_rigid"))
    master, slave = os.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "processes.cli", "join", served.gateway.endpoint, "--as",
                             "player", "--seconds", f"{DEADLINE_S:.0f}"], cwd=ROOT, stdin=slave, stdout=slave, stderr=slave,
                            start_new_session=True, env={**os.environ, "TERM": "xterm", "COLUMNS": "120"})
    os.close(slave)
    screen = bytearray()

    def read_until(check, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and not check():
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    screen.extend(os.read(master, 65536))
                except OSError:  # the child closed the terminal
                    break
        return check()

    try:
        assert read_until(lambda: b"you play A" in screen, DEADLINE_S), screen.decode(errors="replace")[-2000:]
        os.write(master, b"ww")
        assert served.wait_for(lambda: len(served.posted) > 5)
        os.write(master, b"q")
        assert read_until(lambda: b"prediction error at the snapshots' ticks, own bat" in screen, DEADLINE_S)
        assert proc.wait(DEADLINE_S) == 0
        assert b"session ended: quit" in screen
        assert served.wait_for(lambda: served.gateway.counts["quits"] == 1)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(10)
        os.close(master)
        served.close()
