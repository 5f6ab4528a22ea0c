"""The bot brain: any player of the bot API (engine.play.bot) playing one bat of a served match
(`pingpong join --bot [PLAYER]`), shown the predicted state, answering through the arm law."""
from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from engine.play.bot import BotError
from engine.physics.dtypes import BAT_DTYPE, RALLY_DTYPE
from engine.physics.scene import Scene
from engine.physics.compiled import compile_scene
from engine.play.arm import control_bats
from engine.play.players import DEFAULT_BUDGET_S, make_players
from engine.play.rules import Phase
from processes.network import wire
from processes.network.wire import Slot


class BotBrain:
    """One bat of a served match played by `player`: an AI profile ("pro", "club", "novice") or a
    bot ("FILE.py:Class", "module:Class"), through the same seat a match gives it
    (engine.play.players): the same observation, the same checks of its action, the same arm law
    (engine.play.arm.control_bats) turning the plan into the force and torque sent.

    As in a match (engine.play.match), the player decides at every control tick (the scene's ai_hz)
    from the state at that tick, here the predicted present (the tick an input sent now takes
    effect on the server), and its plan takes effect decision_delay ticks later. The snapshot
    carries no shot count, so the brain counts the strikes it sees (the striker changes, or the
    phase leaves waiting-for-serve), which change at the same moments as the match's.

    A decision that raises, returns something malformed or overruns its budget is a fault, as in
    a match: the arm brakes until the next good decision, and the fault is kept in `errors`
    (engine.play.bot.BotError) and reported; the server, which never sees the bot, awards no point for it.

    Raises ValueError (naming the bot) if the player cannot be loaded, made or set up.
    """

    def __init__(self, scene: Scene, slot: Slot, player: str = "pro", seed: int = 0,
                 budget_s: float | None = DEFAULT_BUDGET_S):
        me = slot.bat
        bats = tuple(replace(bat, skill=player if i == me else None, remote=False) for i, bat in enumerate(scene.bats))
        self.scene = replace(scene, bats=bats, effects=scene.effects | {"ai"})
        compiled = compile_scene(self.scene)
        self.model = compiled.model
        self.player, self.spec = me, player
        self.period = compiled.control_period
        self.delay = compiled.decision_delay
        self.players = make_players(self.scene, self.model, seed, self.period, self.delay, budget_s=budget_s)
        for thinker in self.players.thinkers:
            thinker.warm_up()
        self.arm = self.players.ctl.copy()  # the plans in effect
        self._plans: deque[tuple[int, np.ndarray]] = deque()  # (tick it takes effect, ctl) decided, not yet in effect
        self._next_decision: int | None = None
        self.rally = np.zeros((), RALLY_DTYPE)
        self.ball_flat = np.zeros(9)
        self.forces = np.zeros((len(scene.bats), 6))
        self._snapshot_bats = np.zeros(len(scene.bats), BAT_DTYPE)  # a snapshot's bats (no force: unknown here)
        self.errors: list[BotError] = []
        self._last = None
        self._shots = 0

    def control(self, snapshot: wire.Message, dt: float, predictor=None) -> np.ndarray:
        """(6,) force and torque for our bat at the predicted present (predictor, reconciled with
        the snapshot: the arm's PD loop would go unstable on states a round trip old) or, without
        a predictor, at the snapshot's tick. The snapshot says whose turn it is (phase, server,
        striker, rally, score)."""
        if predictor is not None and predictor.tick is not None:
            tick, state = int(predictor.tick), predictor.state
            ball, bats = state.ball[0], state.bats
        else:
            tick, ball, bats = snapshot.tick, None, self._snapshot_bats
            bats["pos"], bats["quat"] = snapshot["bat_pos"], snapshot["bat_quat"]
            bats["vel"], bats["ang_vel"] = snapshot["bat_vel"], snapshot["bat_ang_vel"]
        now = tick * dt
        if ball is None:
            self.ball_flat[0:3], self.ball_flat[3:6], self.ball_flat[6:9] = (
                snapshot["ball_pos"], snapshot["ball_vel"], snapshot["ball_spin"])
        else:
            self.ball_flat[0:3], self.ball_flat[3:6], self.ball_flat[6:9] = ball["pos"], ball["vel"], ball["spin"]
        self._see(snapshot)
        if self._next_decision is None or tick >= self._next_decision:
            self._next_decision = (tick // self.period + 1) * self.period
            for player, fault, detail in self.players.decide(tick, now, self.ball_flat, bats, self.rally):
                self.errors.append(BotError(self.spec, player, tick, fault, detail))
            self._plans.append((tick + self.delay, self.players.ctl.copy()))
        while self._plans and self._plans[0][0] <= tick:
            self.arm[:] = self._plans.popleft()[1]
        control_bats(now, self.players.bat_floats(bats), self.arm, self.players.players, self.forces)
        return self.forces[self.player]

    def _see(self, snapshot: wire.Message) -> None:
        """The referee's public state from the snapshot into the rally record the seat is shown."""
        rally = self.rally
        phase, server, striker = int(snapshot["phase"]), int(snapshot["server"]), int(snapshot["striker"])
        number = int(snapshot["rally"]) - 1  # the wire numbers rallies from 1, the engine from 0
        last = self._last
        if last is None or number != last[0]:
            self._shots = 0
        elif striker != last[2] or (last[1] == Phase.WAITING_SERVE and phase != Phase.WAITING_SERVE):
            self._shots += 1  # a strike: a return (the striker changed) or the service
        self._last = (number, phase, striker)
        rally["rally"], rally["shots"], rally["phase"], rally["server"], rally["striker"] = (
            number, self._shots, phase, server, striker)
        rally["score"], rally["games_won"], rally["winner"] = snapshot["score"], snapshot["games_won"], snapshot["winner"]

    @property
    def stats(self) -> dict:
        """The player's decisions and faults (engine.play.players.Players.stats, our end's)."""
        return {"player": self.spec, **self.players.stats["ab"[self.player]], "errors": len(self.errors)}

