"""The compiled referee (engine.play.judge) against the reference Referee (engine.play.rules): the
same contacts, judged by both, give the same records and points, whatever their order."""
import numpy as np
import pytest

from engine.physics.dtypes import RALLY_DTYPE
from engine.physics.geometry import Body
from engine.play import judge
from engine.play.rules import REASONS, Referee

BODIES = (Body.TABLE, Body.FLOOR, Body.NET, Body.POST, Body.BAT_A, Body.BAT_B)


@pytest.mark.parametrize("best_of", [1, 3])
def test_random_contacts_are_judged_as_the_referee_judges_them(best_of):
    rng = np.random.default_rng(best_of)
    ref = Referee(best_of=best_of, first_server=1)
    record = np.zeros(1, RALLY_DTYPE)
    ref.save(record[0])
    r = record[0]
    ball, world = np.zeros(9), np.zeros(1, [("ball_support", "<i4"), ("time", "<f8")])
    points = 0
    while not ref.match_over:
        # Mostly table bounces and bat strikes, so that rallies run on and games end.
        body = int(rng.choice(BODIES, p=[0.4, 0.04, 0.06, 0.02, 0.24, 0.24]))
        x, y = rng.uniform(-1.7, 1.7), rng.uniform(-0.9, 0.9)
        if rng.uniform() < 0.03:
            expected = ref.ball_out_of_play(x, y)
            won, reason = judge.ball_out_of_play(r, x, y, best_of)
        else:
            expected = ref.on_contact(body, (x, y, 0.0))
            won, reason = judge.on_contact(r, body, x, y, best_of)
        if expected is None:
            assert won == judge.NO_POINT
        else:
            points += 1
            assert (won, REASONS[reason]) == (expected.winner, expected.reason)
        if expected is not None and not ref.match_over:
            ref.next_rally()
            judge.next_rally_and_toss(r, ball, world[0], 2.6)
        saved = np.zeros(1, RALLY_DTYPE)
        ref.save(saved[0])
        saved[0]["rally"], saved[0]["rally_started"] = r["rally"], r["rally_started"]
        assert saved.tobytes() == record.tobytes()
    assert points >= 11 * (best_of // 2 + 1)
    assert r["winner"] == ref.winner
