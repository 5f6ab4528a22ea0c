"""The players' decision gates (engine.play.players.Players.gates, gate_open): what the physics
worker asks to skip a control tick's AI turn says exactly whether Players.decide lets anybody
decide there."""
import numpy as np

from engine.physics.scene import load_scene
from engine.play.match import LocalAI, Match, make_ais
from engine.play.players import decision_key, gate_open

SCENE = load_scene("match_rigid")


class _Gated(LocalAI):
    """The reference driver, asking the gates after the previous turn before every decision."""

    def __init__(self, ais):
        super().__init__(ais)
        n = len(ais)
        self.gates = (np.zeros((n, 4), np.int64), np.zeros(n), np.zeros(n))
        ais.gates(*self.gates)
        self.asked = self.open = 0

    def request(self, match, now):
        expected = gate_open(decision_key(match.rally_record), now, *self.gates)
        super().request(match, now)
        assert self.ais.decided == expected, f"tick {match.current_tick}: gates said {expected}"
        self.ais.gates(*self.gates)
        self.asked += 1
        self.open += expected


def test_the_gates_say_exactly_where_a_player_decides():
    driver = _Gated(make_ais(SCENE, 4))
    match = Match(SCENE, seed=4, ai_driver=driver)
    match.play(max_ticks=40_000)
    assert driver.asked == 40_000 // match.ai_every
    assert 0 < driver.open < driver.asked // 4  # most control ticks need nobody
