"""A browser's player session: `pingpong join --as player` driven by the browser's keys and pointer."""
from __future__ import annotations

import queue
import threading

import numpy as np

from processes.network import wire
from processes.network.client.client import Client


class BrowserPlayer:
    """A browser's player session: `pingpong join --as player` driven by the browser's keys
    and pointer, in a thread of its own (run_session with a KeyboardPilot and a Predictor).

    Args:
        bridge: the web.bridge.WebBridge it plays through (its address, socket options, join
            timeout and counts; its send_text answers the browser). websocket: the browser's
            connection.
        seat: "a", "b" or "any", the seat the browser asked for.
    """

    SHOW_EVERY_S = 1.0 / 60.0

    def __init__(self, bridge, websocket, seat: str):
        self.bridge, self.websocket = bridge, websocket
        self.wanted = {"a": wire.Slot.A, "b": wire.Slot.B, "any": wire.Slot.NONE}[seat]
        self.requests: queue.SimpleQueue = queue.SimpleQueue()
        self.pilot = None
        self._thread = threading.Thread(target=self._run, name="web-bridge-player", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def take(self, request: dict) -> None:
        self.requests.put(request)

    def stop(self, timeout_s: float = 5.0) -> None:
        self.requests.put({"key": "quit"})
        self._thread.join(timeout_s)

    def poll(self, timeout_s: float = 0.0) -> list[str]:
        """run_session's key source: the browser's keys; its aims move the pilot's target here,
        in the session's thread."""
        keys = []
        while True:
            try:
                request = self.requests.get_nowait()
            except queue.Empty:
                return keys
            if "aim" in request and self.pilot is not None:
                self.pilot.aim_at(request["aim"])
            elif "key" in request:
                keys.append(request["key"])

    def _run(self) -> None:
        from processes.network.client.client import Rejected
        from processes.network.client.keyboard import KeyboardPilot
        from processes.network.client.prediction import Predictor
        from processes.network.client.scenes import served_scene
        from processes.network.client.session import SessionOptions, run_session

        bridge = self.bridge
        client = Client(bridge.address, "player", "browser", self.wanted, socket_options=bridge.socket_options)
        try:
            try:
                welcome = client.join(bridge.join_timeout_s)
            except (Rejected, TimeoutError) as err:
                reason = err.reason.name.lower() if isinstance(err, Rejected) else "timeout"
                bridge.send_text(self.websocket, {"rejected": reason, "detail": str(err)})
                return
            try:
                scene = served_scene(client, bridge.join_timeout_s)
            except (TimeoutError, ValueError) as err:  # no scene came, or not the welcome's (SceneError)
                client.leave()
                bridge.send_text(self.websocket, {"rejected": "scene", "detail": str(err)})
                return
            bridge.counts["players"] = bridge.counts.get("players", 0) + 1
            predictor = Predictor(scene, client.slot)
            self.pilot = KeyboardPilot(predictor.model, client.slot)
            bridge.send_text(self.websocket, {"seat": client.slot.name.lower(), "token": client.token.hex()})

            def show(summary, frame) -> None:
                if predictor.tick is None:
                    return
                bat = predictor.bat
                bridge.send_text(self.websocket, {"predicted": {
                    "tick": int(predictor.tick), "bat_pos": np.asarray(bat["pos"]).tolist(),
                    "bat_quat": np.asarray(bat["quat"]).tolist(), "aim": np.asarray(frame["target"]).tolist(),
                    "inputs_sent": summary["inputs_sent"]}})

            summary = run_session(client, welcome, SessionOptions(pilot=self.pilot, keys=self, predictor=predictor,
                                                                 show=show, show_every_s=self.SHOW_EVERY_S))
            bridge.send_text(self.websocket, {"ended": summary["goodbye"], "inputs_sent": summary["inputs_sent"]})
        finally:
            client.close()


__all__ = ["BrowserPlayer"]
