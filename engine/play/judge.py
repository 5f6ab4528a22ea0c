"""The referee's judgement (engine.play.rules.Referee) as numba functions over a RALLY_DTYPE record.

The batched environment (engine.learning.batch) judges N tables' contacts inside one compiled
call; these functions are Referee's rules (ITTF Handbook, chapter 2) on the record the match
keeps the referee in, step for step the same decisions in the same order, so a table judged here
is the table Referee judges (tests/engine/test_judge.py plays both on the same contacts). The
record is kept as Referee.save writes it after every change (server included); what Referee keeps
beside it (the point log, the finished games' scores) is not needed to judge: a point shows as
points_total going up, its winner and reason are returned.

Returns of the judging functions: NO_POINT, or the point's winner (-1 for a let) and its
reason's index in engine.play.rules.REASONS.
"""
from __future__ import annotations

from numba import njit

from engine.physics import equipment
from engine.physics.geometry import Body
from engine.play.rules import REASONS, Phase, Reason

NO_POINT = -2  # no point was decided (a let's winner is -1)
_LET = -1
_HALF_LENGTH = equipment.TABLE_LENGTH / 2
_HALF_WIDTH = equipment.TABLE_WIDTH / 2
_TOSS_X = equipment.TABLE_LENGTH / 2 + 0.1  # m: engine.play.match.Match.toss, 10 cm behind the end line
_TOSS_Z = 0.12
_WAITING_SERVE, _SERVED, _SERVE_BOUNCED, _STRUCK, _BOUNCED, _OVER = (int(p) for p in Phase)
_TABLE, _FLOOR, _NET, _POST, _BAT_A, _BAT_B = (int(b) for b in (Body.TABLE, Body.FLOOR, Body.NET, Body.POST,
                                                                Body.BAT_A, Body.BAT_B))
(_SERVE_MISSED_OWN_COURT, _SERVE_DOUBLE_BOUNCE, _SERVE_WHIFF, _R_NET, _OUT_LONG, _OUT_SIDE, _OWN_COURT,
 _DOUBLE_BOUNCE, _MISSED, _DOUBLE_HIT, _OBSTRUCTION, _R_LET) = (REASONS.index(r) for r in (
    Reason.SERVE_MISSED_OWN_COURT, Reason.SERVE_DOUBLE_BOUNCE, Reason.SERVE_WHIFF, Reason.NET, Reason.OUT_LONG,
    Reason.OUT_SIDE, Reason.OWN_COURT, Reason.DOUBLE_BOUNCE, Reason.MISSED, Reason.DOUBLE_HIT,
    Reason.OBSTRUCTION, Reason.LET))


@njit(cache=True, _nrt=False)
def server(r):
    """Who serves the rally (rule 2.13: two each, one each from 10-10): Referee.server."""
    played = r['score'][0] + r['score'][1]
    turns = played // 2 if played < 20 else 10 + (played - 20)
    first = r['game_first_server']
    return first if turns % 2 == 0 else 1 - first


@njit(cache=True, _nrt=False)
def _court_of(x):
    return 0 if x < 0 else 1


@njit(cache=True, _nrt=False)
def _award(r, winner, reason, best_of):
    """Referee._award: the point to `winner`, the game or the match ended, the ends changed at 5."""
    score = r['score']
    score[winner] += 1
    r['points_total'] += 1
    r['phase'] = _OVER
    a, b = score[0], score[1]
    games = r['games_won']
    if max(a, b) >= 11 and abs(a - b) >= 2:  # Referee._end_game
        w = 0 if a > b else 1
        games[w] += 1
        score[0] = 0
        score[1] = 0
        r['deciding_ends_swapped'] = 0
        r['game_first_server'] = 1 - r['game_first_server']  # rule 2.13.3
        if games[w] > best_of // 2:
            r['winner'] = w
    elif (games[0] + games[1] == best_of - 1 and max(a, b) == 5 and min(a, b) < 5
          and r['deciding_ends_swapped'] == 0):
        r['deciding_ends_swapped'] = 1  # rule 2.14.2
    r['server'] = server(r)
    return winner, reason


@njit(cache=True, _nrt=False)
def _out_reason(r, x, y):
    if _court_of(x) == r['striker']:
        return _R_NET
    return _OUT_LONG if abs(x) > _HALF_LENGTH else _OUT_SIDE


@njit(cache=True, _nrt=False)
def ball_out_of_play(r, x, y, best_of):
    """Referee.ball_out_of_play: the ball hit the floor, left the area or came to rest."""
    phase = r['phase']
    if phase == _OVER or r['winner'] >= 0:
        return NO_POINT, 0
    striker = r['striker']
    if phase == _WAITING_SERVE:
        return _award(r, 1 - server(r), _SERVE_WHIFF, best_of)
    if phase == _BOUNCED:
        return _award(r, striker, _MISSED, best_of)
    if phase == _SERVED:
        return _award(r, 1 - striker, _SERVE_MISSED_OWN_COURT, best_of)
    return _award(r, 1 - striker, _out_reason(r, x, y), best_of)


@njit(cache=True, _nrt=False)
def _strike(r, player, x, y, best_of):
    phase = r['phase']
    if phase == _WAITING_SERVE:
        if player != server(r):
            return _award(r, server(r), _OBSTRUCTION, best_of)
        r['phase'], r['striker'], r['shots'], r['touched_net'] = _SERVED, player, 1, 0
        return NO_POINT, 0
    if player == r['striker']:
        return _award(r, 1 - player, _DOUBLE_HIT, best_of)
    if phase == _BOUNCED:
        r['phase'], r['striker'], r['touched_net'] = _STRUCK, player, 0
        r['shots'] += 1
        return NO_POINT, 0
    if abs(x) <= _HALF_LENGTH and abs(y) <= _HALF_WIDTH:
        return _award(r, 1 - player, _OBSTRUCTION, best_of)
    return _award(r, player, _out_reason(r, x, y), best_of)


@njit(cache=True, _nrt=False)
def _bounce(r, x, y, best_of):
    court = _court_of(x)
    striker = r['striker']
    phase = r['phase']
    if phase == _WAITING_SERVE:
        return _award(r, 1 - server(r), _SERVE_WHIFF, best_of)
    if phase == _SERVED:
        if court != striker:
            return _award(r, 1 - striker, _SERVE_MISSED_OWN_COURT, best_of)
        r['phase'], r['touched_net'] = _SERVE_BOUNCED, 0
        return NO_POINT, 0
    if phase == _SERVE_BOUNCED:
        if court == striker:
            return _award(r, 1 - striker, _R_NET if r['touched_net'] else _SERVE_DOUBLE_BOUNCE, best_of)
        if r['touched_net']:  # Referee._let: replayed
            r['points_total'] += 1
            r['phase'] = _OVER
            return _LET, _R_LET
        r['phase'] = _BOUNCED
        return NO_POINT, 0
    if phase == _STRUCK:
        if court == striker:
            return _award(r, 1 - striker, _R_NET if r['touched_net'] else _OWN_COURT, best_of)
        r['phase'] = _BOUNCED
        return NO_POINT, 0
    return _award(r, striker, _DOUBLE_BOUNCE, best_of)


@njit(cache=True, _nrt=False)
def on_contact(r, body, x, y, best_of):
    """Referee.on_contact: judge one contact of the ball with `body` (Body id) at (x, y) m."""
    if r['phase'] == _OVER or r['winner'] >= 0:
        return NO_POINT, 0
    if body == _NET or body == _POST:
        r['touched_net'] = 1
        return NO_POINT, 0
    if body == _BAT_A or body == _BAT_B:
        return _strike(r, body - _BAT_A, x, y, best_of)
    if body == _TABLE:
        return _bounce(r, x, y, best_of)
    if body == _FLOOR:
        return ball_out_of_play(r, x, y, best_of)
    return NO_POINT, 0


@njit(cache=True, _nrt=False)
def next_rally_and_toss(r, ball, world, toss_speed):
    """Referee.next_rally, then engine.play.match.Match.toss: the server tosses the ball from 10 cm
    behind its end line straight up. ball: (9,) the ball's flat state; world: its WORLD_DTYPE record."""
    serving = server(r)
    r['phase'] = _WAITING_SERVE
    r['striker'] = serving
    r['shots'] = 0
    r['touched_net'] = 0
    r['server'] = serving
    r['rally'] += 1
    sign = -1.0 if serving == 0 else 1.0
    ball[0], ball[1], ball[2] = sign * _TOSS_X, 0.0, _TOSS_Z
    ball[3], ball[4], ball[5] = 0.0, 0.0, toss_speed
    ball[6], ball[7], ball[8] = 0.0, 0.0, 0.0
    world['ball_support'] = 0
    r['rally_started'] = world['time']
