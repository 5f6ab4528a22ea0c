"""The referee against scripted contact sequences (ITTF Handbook, chapter 2)."""
import pytest

from engine.physics.geometry import Body
from engine.play.rules import Phase, Reason, Referee

A, B = 0, 1
BAT = {A: Body.BAT_A, B: Body.BAT_B}


def court(ref, player, y=0.0):
    """A point on `player`'s court in the referee's current ends."""
    return (ref.end_sign(player) * 0.8, y, 0.02)


def serve_legal(ref):
    s, r = ref.server, ref.receiver
    assert ref.on_contact(BAT[s], (ref.end_sign(s) * 1.5, 0, 0.2)) is None
    assert ref.on_contact(Body.TABLE, court(ref, s)) is None
    assert ref.on_contact(Body.TABLE, court(ref, r)) is None
    return s, r


def test_rally_won_by_a_double_bounce():
    ref = Referee()
    s, r = serve_legal(ref)
    ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))  # return
    ref.on_contact(Body.TABLE, court(ref, s))
    point = ref.on_contact(Body.TABLE, court(ref, s, 0.3))
    assert (point.winner, point.reason, point.shots) == (r, Reason.DOUBLE_BOUNCE, 2)
    assert ref.phase == Phase.OVER


def test_missed_return():
    ref = Referee()
    s, r = serve_legal(ref)
    point = ref.on_contact(Body.FLOOR, (ref.end_sign(r) * 2.5, 0.0, -0.74))
    assert (point.winner, point.reason) == (s, Reason.MISSED)


def test_service_touching_the_net_then_landing_well_is_a_let():
    ref = Referee()
    s, r = ref.server, ref.receiver
    ref.on_contact(BAT[s], (ref.end_sign(s) * 1.5, 0, 0.2))
    ref.on_contact(Body.TABLE, court(ref, s))
    ref.on_contact(Body.NET, (0.0, 0.0, 0.14))
    point = ref.on_contact(Body.TABLE, court(ref, r))
    assert point.reason == Reason.LET and point.winner == -1
    assert ref.score == [0, 0]
    ref.next_rally()
    assert ref.server == s  # a let is replayed by the same server


def test_net_touch_during_a_rally_is_fine():
    ref = Referee()
    s, r = serve_legal(ref)
    ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))
    assert ref.on_contact(Body.NET, (0.0, 0.0, 0.15)) is None
    assert ref.on_contact(Body.TABLE, court(ref, s)) is None
    assert ref.phase == Phase.BOUNCED


@pytest.mark.parametrize(
    "contacts, winner_is_receiver, reason",
    [
        # served straight onto the receiver's court
        ([("bat_s", 1.5), ("table", "r")], True, Reason.SERVE_MISSED_OWN_COURT),
        # bounced twice on the server's court
        ([("bat_s", 1.5), ("table", "s"), ("table", "s")], True, Reason.SERVE_DOUBLE_BOUNCE),
        # into the net, dropping to the floor on the server's side
        ([("bat_s", 1.5), ("table", "s"), ("net", 0.0), ("floor", "s")], True, Reason.NET),
        # over everything, onto the floor beyond the receiver's end
        ([("bat_s", 1.5), ("table", "s"), ("floor_long", "r")], True, Reason.OUT_LONG),
        # the tossed ball fell on the table unstruck
        ([("table", "s")], True, Reason.SERVE_WHIFF),
        # the receiver struck the ball before it bounced, above the table
        ([("bat_s", 1.5), ("table", "s"), ("bat_r_over_table", 0.5)], False, Reason.OBSTRUCTION),
        # the server struck it twice
        ([("bat_s", 1.5), ("bat_s", 1.5)], True, Reason.DOUBLE_HIT),
    ],
)
def test_service_faults(contacts, winner_is_receiver, reason):
    ref = Referee()
    s, r = ref.server, ref.receiver
    where = {"s": s, "r": r}
    point = None
    for kind, arg in contacts:
        if kind == "bat_s":
            point = ref.on_contact(BAT[s], (ref.end_sign(s) * arg, 0, 0.2))
        elif kind == "bat_r_over_table":
            point = ref.on_contact(BAT[r], (ref.end_sign(r) * arg, 0, 0.2))
        elif kind == "table":
            point = ref.on_contact(Body.TABLE, court(ref, where[arg]))
        elif kind == "net":
            point = ref.on_contact(Body.NET, (0.0, 0.0, 0.1))
        elif kind == "floor":
            point = ref.on_contact(Body.FLOOR, (ref.end_sign(where[arg]) * 0.5, 0, -0.74))
        elif kind == "floor_long":
            point = ref.on_contact(Body.FLOOR, (ref.end_sign(where[arg]) * 3.0, 0, -0.74))
    assert point is not None and point.reason == reason
    assert point.winner == (r if winner_is_receiver else s)


def test_return_onto_own_court_and_out_side():
    ref = Referee()
    s, r = serve_legal(ref)
    ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))
    point = ref.on_contact(Body.TABLE, court(ref, r))
    assert (point.winner, point.reason) == (s, Reason.OWN_COURT)
    ref.next_rally()
    s, r = serve_legal(ref)
    ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))
    point = ref.ball_out_of_play(ref.end_sign(s) * 0.5, 1.2)  # beside the table on s's side
    assert (point.winner, point.reason) == (s, Reason.OUT_SIDE)


def test_return_into_the_net_falling_back_is_net():
    ref = Referee()
    s, r = serve_legal(ref)
    ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))
    assert ref.on_contact(Body.NET, (0.0, 0.0, 0.1)) is None
    point = ref.on_contact(Body.TABLE, court(ref, r))  # fell back off the net onto the striker's court
    assert (point.winner, point.reason) == (s, Reason.NET)


def test_service_into_the_net_falling_back_is_net():
    ref = Referee()
    s, r = ref.server, ref.receiver
    ref.on_contact(BAT[s], (ref.end_sign(s) * 1.5, 0, 0.2))
    ref.on_contact(Body.TABLE, court(ref, s))
    ref.on_contact(Body.NET, (0.0, 0.0, 0.1))
    point = ref.on_contact(Body.TABLE, court(ref, s, 0.2))
    assert (point.winner, point.reason) == (r, Reason.NET)


def play_point(ref, winner):
    """Script a rally that `winner` wins (the loser misses a legal return)."""
    s, r = serve_legal(ref)
    if winner == s:
        point = ref.ball_out_of_play(ref.end_sign(r) * 2.5, 0.0)
    else:
        ref.on_contact(BAT[r], (ref.end_sign(r) * 1.6, 0, 0.2))
        ref.on_contact(Body.TABLE, court(ref, s))
        point = ref.ball_out_of_play(ref.end_sign(s) * 2.5, 0.0)
    assert point.winner == winner
    if not ref.match_over:
        ref.next_rally()
    return point


def test_service_changes_every_two_points_then_every_point_from_10_all():
    ref = Referee(first_server=A)
    servers = []
    for winner in [A, B] * 10:  # reaches 10-10
        servers.append(ref.server)
        play_point(ref, winner)
    assert servers == [A, A, B, B] * 5  # rule 2.13.3: two services each
    assert ref.score == [10, 10]
    deuce = []
    for winner in [A, B, A, B]:
        deuce.append(ref.server)
        play_point(ref, winner)
    assert deuce == [A, B, A, B]  # rule 2.13.4: one service each from 10-10
    play_point(ref, A)
    play_point(ref, A)  # 14-12: won by two
    assert ref.games == [(14, 12)] and ref.score == [0, 0]


def test_next_game_swaps_first_server_and_ends():
    ref = Referee(first_server=A)
    assert ref.end_sign(A) == -1
    for _ in range(11):
        play_point(ref, A)
    assert ref.games == [(11, 0)]
    assert ref.server == B  # rule 2.13.3: who served first receives first in the next game
    assert ref.ends_changed == 1  # rule 2.14.1, recorded; the simulated hall is symmetric


def test_best_of_five_and_deciding_game_ends_at_five():
    ref = Referee(best_of=5)
    for game_winner in [A, B, A, B]:
        for _ in range(11):
            play_point(ref, game_winner)
    assert ref.games_won == [2, 2] and ref.game == 4
    changed = ref.ends_changed
    for _ in range(4):
        play_point(ref, A)
    assert ref.ends_changed == changed
    play_point(ref, A)  # A reaches 5: rule 2.14.2, the players change ends
    assert ref.ends_changed == changed + 1
    for _ in range(6):
        play_point(ref, A)
    assert ref.match_over and ref.winner == A
    assert ref.games[-1] == (11, 0)
    assert ref.on_contact(Body.TABLE, (0.5, 0, 0.02)) is None  # nothing happens after the match


def test_best_of_must_be_odd():
    with pytest.raises(ValueError, match="best_of must be an odd number"):
        Referee(best_of=4)
