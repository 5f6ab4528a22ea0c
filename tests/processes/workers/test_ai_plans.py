"""The AI worker's side of a turn (processes.workers.ai.Answerer) in this process: the players
deciding from a copy of each control tick's state, their thinking spread between the turns, and
the plans taken up only where a player decided, give the same match bit for bit as the
reference (engine.play.match.LocalAI)."""
from collections import deque

import numpy as np
import pytest

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.scene import load_scene
from engine.play.match import Match, make_ais
from processes.workers.ai import Answerer

SCENE = load_scene("match_rigid")


class _Follow:
    """An ai_driver: at every control tick the AI worker's Answerer decides from a copy of the
    state (as from the AI's view); where a player decided, its plans take effect match.delay
    ticks later (as AIDriver takes them). A stroke being thought out gets `think_steps` of
    BatAI.think_step per control tick, the rest when due (as between turns)."""

    def __init__(self, scene, seed: int, think_steps: int):
        match = Match(scene, seed)  # only for its model: the AIs must be built as the reference's
        self.ais = make_ais(scene, seed, eager=False)
        self.answerer = Answerer(self.ais, len(scene.bats))
        self.view = np.zeros(1, physics_snapshot_dtype(len(scene.bats)))
        self.think_steps = think_steps
        self.pending = deque()
        self.turns = self.decisions = 0

    def collect(self, match: Match, tick: int) -> list:
        if self.pending and self.pending[0][0] == tick:
            match.arm[:] = self.pending.popleft()[1]
        return []  # no bots, no faults

    def resume(self, match: Match, tick: int) -> None:
        raise AssertionError("not restored")

    def request(self, match: Match, now: float) -> None:
        match.save(self.view)
        self.turns += 1
        record = self.answerer.answer(self.view, self.turns)[0]
        if record["changed"]:
            self.pending.append((int(match.state.world[0]["tick"]) + match.delay, record["ctl"][:len(self.ais)].copy()))
            self.decisions += 1
        for ai in self.ais.thinkers:
            for _ in range(self.think_steps):
                ai.think_step()


def _first_difference(seed: int, ticks: int, think_steps: int):
    """Both matches side by side, compared at every stop of Match.tick (every control tick, every
    contact event): (tick, None) at the first difference, else (None, driver)."""
    reference = Match(SCENE, seed)
    driver = _Follow(SCENE, seed, think_steps)
    follower = Match(SCENE, seed, ai_driver=driver)
    while int(reference.state.world[0]["tick"]) < ticks and not reference.referee.match_over:
        reference.tick(ticks)
        follower.tick(ticks)
        if reference.state.record.tobytes() != follower.state.record.tobytes():
            return int(reference.state.world[0]["tick"]), None
    return None, driver


@pytest.mark.parametrize("seed, think_steps", [(0, 0), (1, 3), (5, 1)])
def test_following_the_plans_between_decisions_is_the_reference_bit_for_bit(seed, think_steps):
    at, driver = _first_difference(seed, 40_000, think_steps)
    assert at is None, f"seed {seed}: the states differ from tick {at}"
    # Most turns need no decision: the AI worker answers them in microseconds.
    assert 0 < driver.decisions < driver.turns / 5


@pytest.mark.long
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_following_the_plans_over_whole_matches(seed):
    at, driver = _first_difference(seed, 2_000_000, 1)
    assert at is None, f"seed {seed}: the states differ from tick {at}"
