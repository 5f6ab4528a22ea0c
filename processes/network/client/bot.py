"""The bot brain: engine.ai.BatAI playing one bat from the server's snapshots (`pingpong join --bot`)."""
from __future__ import annotations

import numpy as np

from engine.ai import SKILLS, BatAI
from engine.dtypes import BAT_DTYPE
from engine.rules import Phase, next_striker
from engine.scene import Scene
from engine.world import build_model
from processes.network import wire
from processes.network.wire import Slot


class BotBrain:
    """engine.ai.BatAI playing one bat from the server's snapshots (`pingpong join --bot`).

    The AI sees what the snapshot carries. The rally key of the in-process match is (rally,
    shots); the snapshot carries no shot count, so the bot counts the strikes it sees (the
    striker changes, or the phase leaves waiting-for-serve), which changes at the same moments.
    """

    def __init__(self, scene: Scene, slot: Slot, skill: str = "pro", seed: int = 0):
        self.scene = scene
        self.model = build_model(self.scene)
        self.player = slot.bat
        self.ai = BatAI(self.model, self.player, SKILLS[skill], seed=seed * 1000 + self.player)
        self.ai.warm_up()
        self.bat = np.zeros((), BAT_DTYPE)
        self.ball_flat = np.zeros(9)
        self.out = np.zeros(6)
        self._last = None
        self._turns = 0

    def control(self, snapshot: wire.Message, dt: float, predictor=None) -> np.ndarray:
        """(6,) force and torque for our bat after this snapshot.

        predictor: a prediction.Predictor reconciled with the snapshot: the AI then decides from
        the predicted ball and bat at the predicted tick (the server's present, as far as the
        client knows), not from the snapshot's past: the arm's PD loop would otherwise act on
        states a round trip old, and a loop with kd = 60/s goes unstable beyond ~25 ms of delay.
        The snapshot still says whose turn it is (phase, server, striker, rally).
        """
        p = self.player
        if predictor is not None and predictor.tick is not None:
            ball, bat, now = predictor.ball, predictor.bat, predictor.tick * dt
            self.ball_flat[0:3], self.ball_flat[3:6], self.ball_flat[6:9] = ball["pos"], ball["vel"], ball["spin"]
            self.bat["pos"], self.bat["quat"], self.bat["vel"], self.bat["ang_vel"] = (
                bat["pos"], bat["quat"], bat["vel"], bat["ang_vel"])
        else:
            now = snapshot.tick * dt
            self.ball_flat[0:3], self.ball_flat[3:6], self.ball_flat[6:9] = (snapshot["ball_pos"], snapshot["ball_vel"],
                                                                    snapshot["ball_spin"])
            self.bat["pos"], self.bat["quat"] = snapshot["bat_pos"][p], snapshot["bat_quat"][p]
            self.bat["vel"], self.bat["ang_vel"] = snapshot["bat_vel"][p], snapshot["bat_ang_vel"][p]
        phase, server, striker, rally = int(snapshot["phase"]), snapshot["server"], snapshot["striker"], snapshot["rally"]
        last = self._last
        if last is None or rally != last[0]:
            self._turns = 0
        elif striker != last[2] or (last[1] == Phase.WAITING_SERVE and phase != Phase.WAITING_SERVE):
            self._turns += 1  # a strike: a return (the striker changed) or the service
        self._last = (rally, phase, striker)
        my_turn = next_striker(phase, int(server), int(striker)) == p
        return self.ai.control(now, self.ball_flat, self.bat, (rally, self._turns), my_turn,
                               phase == Phase.WAITING_SERVE, -1 if p == 0 else 1, self.out)
