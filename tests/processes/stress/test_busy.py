"""`pingpong stress --scenario busy`, short: a served cloth match beside two CPU hogs keeps its
promises (the scenario's checks: no worker raised, the still bat at rest, heartbeats within a
third of the timeout, the point events equal to the referee's log, every client told why it
ended). Counts and promises only: how fast the busy machine ran is reported, never asserted."""
import argparse

import pytest

from processes.stress import scenarios as stress


def test_a_served_cloth_match_beside_two_hogs_slows_down_and_never_breaks():
    pytest.importorskip("websockets")
    args = argparse.Namespace(duration=6.0, hogs=2, hz=120, busy_spectators=10, busy_browsers=3, seed=0)
    result = stress.run_scenario("busy", args)
    assert result["problems"] == [], "\n".join(result["problems"])
    assert result["ok"] and result["crashes"] == 0 and result["lost_points"] == 0 and result["leaked_shm"] == 0
    c = result["counts"]
    assert c["hogs"] == 2 and c["spectators"] == 10 and c["browsers"] == 3
    assert c["endings"]["spectators"] == {"shutdown": 10} or sum(c["endings"]["spectators"].values()) == 10
    assert c["snapshot_hz"] is not None and c["browser_snapshots_min"] > 0  # the match was seen
    assert c["still_bat_speed_max"] <= c["still_bat_speed_bound"] + 1e-9  # the scenario's bound (its docstring)
