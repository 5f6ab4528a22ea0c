"""A worker's timeline: marks only where the state changes, saved and loaded by worker, the
share of the wall time in which two workers worked at once, and who worked while the net did not."""
import numpy as np
import pytest

from processes.runtime import timeline
from processes.runtime.timeline import IDLE, MARK_DTYPE, THINK, WAIT_AI, WORK, Timeline


def _marks(*pairs):
    return np.array(list(pairs), MARK_DTYPE)


def test_busy_share_counts_the_overlap_of_the_workers_at_work():
    # physics works 0-4 s (waits for the AI 2-3), the AI thinks 1-2 and works 2-3, the net works 3.5-6.
    marks = {"physics": _marks((0.0, WORK), (2.0, WAIT_AI), (3.0, WORK), (4.0, IDLE)),
             "ai": _marks((0.0, IDLE), (1.0, THINK), (2.0, WORK), (3.0, IDLE)),
             "net": _marks((0.0, IDLE), (3.5, WORK), (6.0, IDLE))}
    share = timeline.busy_share(marks, 0.0, 8.0)
    # two at once: 1-2 (physics, AI) and 3.5-4 (physics, net) = 1.5 s; one: 0-1, 2-3, 3-3.5, 4-6 = 4.5 s
    assert share == pytest.approx({"none": 2.0 / 8, "one": 4.5 / 8, "two": 1.5 / 8}, abs=1e-12)  # exact sums of spans
    window = timeline.busy_share(marks, 1.5, 2.5)  # clipped to the window
    assert window == pytest.approx({"none": 0.0, "one": 0.5, "two": 0.5}, abs=1e-12)


def test_the_wall_time_beside_the_net_is_split_by_who_worked_while_it_did_not():
    # The same three workers: the net works 3.5-6; before it, physics alone 0-1, physics and AI
    # 1-2, AI alone 2-3 (the physics waits), physics alone 3-3.5; after it nobody, 6-8.
    marks = {"physics": _marks((0.0, WORK), (2.0, WAIT_AI), (3.0, WORK), (4.0, IDLE)),
             "ai": _marks((0.0, IDLE), (1.0, THINK), (2.0, WORK), (3.0, IDLE)),
             "net": _marks((0.0, IDLE), (3.5, WORK), (6.0, IDLE))}
    share = timeline.shares_beside(marks, "net", 0.0, 8.0)
    assert share == pytest.approx({"net": 2.5 / 8, "physics": 1.5 / 8, "ai+physics": 1.0 / 8, "ai": 1.0 / 8,
                                   "none": 2.0 / 8}, abs=1e-12)  # exact sums of spans
    assert sum(share.values()) == pytest.approx(1.0, abs=1e-12)


def test_a_timeline_marks_changes_of_state_and_loads_by_worker(tmp_path):
    first = Timeline(str(tmp_path), "ai")
    for state in (WORK, WORK, THINK, THINK, WORK):
        first.mark(state)
    first.save()  # ends idle
    assert list(first.marks["state"][:first.count]) == [WORK, THINK, WORK, IDLE]
    other = Timeline(str(tmp_path), "physics")
    other.mark(WORK)
    other.save()
    loaded = timeline.load(str(tmp_path))
    assert set(loaded) == {"ai", "physics"}
    assert list(loaded["ai"]["state"]) == [WORK, THINK, WORK, IDLE]
    assert np.all(np.diff(loaded["ai"]["t"]) >= 0)  # the monotonic clock
