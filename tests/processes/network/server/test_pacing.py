"""SnapshotPacer on a clock the test drives: the snapshots' grid in match time, the cap in wall
time, and a clock that stands (a paused match) still seen by the clients."""
from __future__ import annotations

from processes.network.server.pacing import SnapshotPacer

DT = 0.001  # s, the tick
HZ = 100  # snapshots per second: one every 10 ticks
PACE = 1.001  # wall s per match s of the "realtime" clocks: just slower, so no wall time falls
# on the wall grid's float edge, where a poll one tick later sends instead


def _sent(pacer: SnapshotPacer, calls) -> list[tuple[float, int]]:
    """The (wall s, tick) of every call of `calls` [(wall s, tick)] that the pacer says is due."""
    return [(now, tick) for now, tick in calls if pacer.due(now, tick, tick * DT)]


def test_a_realtime_clock_gets_one_snapshot_every_ten_ticks():
    calls = [(tick * DT * PACE, tick) for tick in range(0, 1000)]  # a poll every tick, realtime
    sent = _sent(SnapshotPacer(HZ, DT), calls)
    assert [tick for _, tick in sent] == list(range(0, 1000, 10))  # the grid of ticks, exactly


def test_a_slow_server_sends_as_often_in_match_time():
    calls = [(tick * DT * 2, tick) for tick in range(0, 1000)]  # half realtime
    sent = _sent(SnapshotPacer(HZ, DT), calls)
    assert [tick for _, tick in sent] == list(range(0, 1000, 10))  # every 10 ticks, at 50 a wall second


def test_a_clock_that_stops_between_two_snapshots_has_its_tick_sent_each_period():
    # the match pauses at tick 1037 (3 ticks short of the grid's next, 1040) for 2 s of polls
    # every millisecond: its standing tick is sent once it stood a period, then once a period
    pacer = SnapshotPacer(HZ, DT)
    before = _sent(pacer, [(tick * DT * PACE, tick) for tick in range(0, 1038)])
    assert before[-1][1] == 1030
    stop = 1037 * DT * PACE
    paused = _sent(pacer, [(stop + i * DT, 1037) for i in range(1, 2001)])
    assert {tick for _, tick in paused} == {1037}
    assert len(paused) in (199, 200)  # one a period over 2 s, the first after a whole period
    assert paused[0][0] - stop >= 0.99 / HZ  # not before the tick stood a period (0.99: the float clock)
    gaps = [b[0] - a[0] for a, b in zip(paused, paused[1:])]
    assert max(gaps) <= 1.01 / HZ  # and never a period and more without one (1 ms polls)
    after = _sent(pacer, [(stop + 2.0 + (tick - 1037) * DT * PACE, tick) for tick in range(1038, 1100)])
    assert [tick for _, tick in after] == list(range(1040, 1100, 10))  # the grid goes on
