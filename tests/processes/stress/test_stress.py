"""`pingpong stress`, scaled down: each scenario against a real served match and client processes.

Counts and invariants only, never timings or how busy the machine was (a shared 2-core VM, or
a slower one). Every scenario runs its own server and swarm processes on 127.0.0.1 random
ports; stress.run_scenario kills and reaps all of them (whole process sessions) whatever
happens, and every wait inside is bounded.
"""
import argparse
import os

import pytest

from processes.stress import scenarios as stress
from processes.stress.harness import Child
from processes.cli import main
from tests.waits import DEADLINE_S


def _args(**overrides) -> argparse.Namespace:
    settings = dict(spectators=50, players=2, hz=120, duration=2.0, churn=200, churn_places=16, churn_seconds=60.0,
                    malformed=5000, malformed_rate=5000, kill=1, kill_spectators=20, seed=0, browsers=10,
                    abuse_seconds=2.0, abuse_spectators=4)
    settings.update(overrides)
    return argparse.Namespace(**settings)


def _clean(result: dict) -> None:
    """The invariants every scenario shares."""
    assert result["problems"] == [], "\n".join(result["problems"])
    assert result["crashes"] == 0 and result["lost_points"] == 0
    assert result["leaked_fds"] == 0 and result["leaked_shm"] == 0, result["fds"]
    assert result["ok"]


def test_load_every_spectator_watches_the_whole_match_and_is_told_it_ended():
    result = stress.run_scenario("load", _args())
    _clean(result)
    c = result["counts"]
    assert c["welcomed"] == 50 and c["goodbye_match_over"] == 50
    assert c["fanout"] == "pub" and c["on_feed"] == 50  # every spectator watched on the feed
    assert c["gateway_snapshots_published"] > 0 and c["gateway_snapshots_sent"] < c["gateway_snapshots_published"] * 3
    assert c["snapshots_received"] > 50 and c["invalid_snapshots"] == 0
    assert c["score_regressions"] == 0 and c["tick_regressions"] == 0
    # a bot reading behind may miss the goodbye (the gateway closes with linger 0; reported as a finding)
    assert all(bot["inputs_sent"] > 0 and bot["goodbye"] in ("match_over", "server_lost") for bot in c["bots"])
    assert sum(bot["goodbye"] == "server_lost" for bot in c["bots"]) == c["bots_without_goodbye"]
    assert 0 < result["latency_ms"]["n"] <= c["snapshots_received"]  # those sent once the match had started
    assert 0 < result["gateway_latency_ms"]["n"] <= c["gateway_snapshots_published"]  # the server's own part
    assert result["tick_jitter_ms"]["n"] > 0 and "gateway" in result["cpu_pct"]
    # Whether one swarm process kept up with 50 spectators is the machine's business (other jobs on
    # its cores starve it); that the result says which it was is the product's.
    swarm = result["swarm"]
    assert result["limited_by_load_generator"] == bool(swarm["saturated"])
    assert any("limited by the load generator" in f for f in result["findings"]) == bool(swarm["saturated"])
    assert swarm["received"] >= c["snapshots_received"] // 2 and swarm["cpu_us_per_message"] > 0


def test_the_server_and_the_load_generator_get_cores_apart_only_where_there_are_enough():
    from processes.stress.scenarios.load import split_cores

    assert split_cores([0, 1]) is None and split_cores([0, 1, 2]) is None
    assert split_cores([0, 1, 2, 3]) == ([0, 1], [2, 3]) and split_cores([4, 5, 6, 7, 8]) == ([4, 5], [6, 7, 8])


def test_the_gateways_own_latency_is_from_the_tick_coming_out_to_its_send():
    import numpy as np

    from processes.stress.report import gateway_latency

    clock = {"ticks": np.array([0, 1, 2, 4]), "times": np.array([0.0, 1.0, 2.0, 4.0])}  # tick 3 not seen
    sends = np.array([(0, 0.5),  # tick 0: the match had not started
                      (1, 1.003), (2, 2.001),
                      (2, 2.5),  # a standing clock's tick again: not a new snapshot
                      (3, 4.002)])  # tick 3 was out by the time tick 4 was seen
    assert gateway_latency(clock, sends) == {"p50": 2.0, "p99": 2.98, "max": 3.0, "n": 3}
    assert gateway_latency(clock, None)["n"] == 0


def test_churn_leaves_every_seat_and_spectator_place_free():
    result = stress.run_scenario("churn", _args())
    _clean(result)
    c = result["counts"]
    assert c["cycles"] == 200 and c.get("join_timeouts", 0) == 0
    assert c["left_goodbye"] > 0 and c["left_abrupt"] > 0  # both ways of leaving happened
    assert c.get("player_welcomed.A", 0) + c.get("player_welcomed.B", 0) > 0 and c["spectator_welcomed"] > 0
    assert c["fill_welcomed"] == 16 + 2 and c["fill_rejected"] == {"full": 2}  # exactly the limits, no leak
    assert c["gateway_fds_after"] <= c["gateway_fds_before"]
    # the server was stopped, not at a match's end: the gateway's counters came anyway
    assert result["gateway"]["spectators_joined"] >= c["spectator_welcomed"] and result["gateway"]["end"] == "shutdown"


def test_cable_pull_is_detected_by_heartbeat_and_the_seat_is_reclaimable():
    result = stress.run_scenario("cable", _args())
    _clean(result)
    c = result["counts"]
    side = c["pulled_slot"]
    assert c["during_grace_newcomer"] == "full"  # the seat waits for its token
    assert c["pulled_goodbye"] == "TIMEOUT" and c["watcher_goodbye"] == "TIMEOUT"  # sent into the hole
    assert c["token_rejoin"] == side and c["after_grace_newcomer"] == side
    assert c["silent_goodbye"] == "TIMEOUT" and c["spectator_fill"] == {"NONE": 4, "full": 1}


def test_kills_are_recovered_and_a_full_server_says_goodbye_to_everyone():
    result = stress.run_scenario("kill", _args())
    _clean(result)
    c = result["counts"]
    assert c["restarts"] == {"physics": 1, "gateway": 1}
    assert c["ticks"][0] < c["ticks"][1] < c["ticks"][2]  # the match went on through both restarts
    assert c["points_after_restart"] >= c["points_before_physics_kill"]
    assert c["keep_rejoined"] == c["keep_welcomed"] == 10  # every watcher joined the new gateway
    assert c["fill_welcomed"] == 12 and c["fill_rejected"] == {"full": 1}  # every place taken
    assert c["goodbye_shutdown"] == c["clients_at_shutdown"] == 22


# Was behind `make test-long`: on a loaded machine one of the nine sessionless sockets' closing
# round trips came back unsynced ("8/9 sockets"). Two causes found in the code (not caught in the
# act): a reject ("full") to one of the valid
# player hellos in the flood, answered by a loaded gateway after the flood's last drain, ended the
# wait for the sync hello's welcome; and the oversized frames' socket loses whatever follows an
# oversized frame (libzmq drops that connection). The round trips now wait for the welcome only,
# on a new connection after the oversized frames. Since: 13 runs passed (up to 3 at once, load
# 5-6); 3 more, at once, hit the old 90 s alarm while engine/ had just changed (a cold numba
# cache compiles for minutes): hence the suite's one long deadline, and `make test`'s warm-up.
def test_malformed_messages_are_all_counted_by_the_gateway_and_the_match_goes_on():
    result = stress.run_scenario("malformed", _args())
    _clean(result)
    c = result["counts"]
    assert c["sent"] == 5000 and set(c["by_class"]) == set(stress_classes())
    assert c["mismatched_counters"] == {} and c["unexpected_counters"] == {}
    assert c["gateway_dropped_total"] == c["expected_dropped_total"] > 3000
    assert c["kicks"] >= 2 and c["legit_goodbyes"] == {"match_over": 5}


def stress_classes():
    from processes.stress.swarm.malformed import CLASSES

    return CLASSES


def test_abuse_hostile_peers_are_bounded_cut_and_counted_and_the_stop_stays_clean():
    result = stress.run_scenario("abuse", _args())
    # every invariant but the honest spectators' rates, which other work on the machine breaks too
    # (the scenario reports them, and `pingpong stress` exits 1 on them)
    assert [p for p in result["problems"] if p not in result["rate_problems"]] == [], "\n".join(result["problems"])
    assert result["crashes"] == 0 and result["leaked_shm"] == 0 and result["leaked_fds"] == 0
    c = result["counts"]
    attacks = c["attacks"]
    assert attacks["flood"]["sent"] > 0 and c["counters"]["inputs_coalesced"] > 0
    assert attacks["multipart"]["cut"] == attacks["multipart"]["peers"] == 4
    assert c["counters"]["disconnected.held_bytes"] >= 4
    assert attacks["oversized"]["announced_cut"] == attacks["oversized"]["announced_1gib"] > 0
    assert attacks["oversized"]["big_frame_cut"] == attacks["oversized"]["big_frames"] > 0
    assert attacks["hellos"]["sockets"] == 500 and attacks["hellos"]["probe"]["answer"] == "welcome"
    assert c["honest_rejected"] == {} and c["honest_goodbyes"] == {"shutdown": 4}
    assert c["signals_sent"] >= 2 and result["gateway"]["end"] == "shutdown"
    assert c["gateway_rss_growth_max_mb"]["multipart"] <= 64 and c["gateway_rss_after_mb"] <= 16


def test_web_every_browser_of_one_bridge_gets_the_snapshots():
    pytest.importorskip("websockets")
    result = stress.run_scenario("web", _args())
    _clean(result)
    c = result["counts"]
    assert c["browsers"] == 10 and c["browser_errors"] == 0 and c["snapshots_per_browser_min"] > 0
    assert result["cpu_pct"]["bridge"] is not None  # the bridge ran through the whole window


def test_a_bad_scenario_name_is_refused_with_the_choices(capsys):
    assert main(["stress", "--scenario", "load,flood"]) == 2
    err = capsys.readouterr().err
    assert "flood" in err and "load,churn,cable,kill,malformed" in err
    assert main(["stress", "--spectators", "0"]) == 2
    assert "--spectators must be at least 1" in capsys.readouterr().err
    assert main(["stress", "--scenario", "load", "--swarm-only"]) == 2  # no --target
    assert "--swarm-only needs --target" in capsys.readouterr().err
    assert main(["stress", "--swarm-only", "--target", "tcp://127.0.0.1:1"]) == 2  # every scenario
    assert "run the load scenario alone" in capsys.readouterr().err


# (competitors on the swarm's CPU, spectators): each try starves the swarm harder than the one before
STARVING = ((1, 50), (3, 200))


def _fell_behind(result: dict) -> bool:
    """The swarm fell behind by the spectators' own counts (under half the feed's snapshots seen,
    or under half its rate) or by its threads' run-queue times (wanting a CPU over half the time)."""
    c, swarm = result["counts"], result["swarm"]
    return (c["missed_pct"] >= 50.0 or (c["rate_median_hz"] or 0.0) < 0.5 * c["snapshot_hz"]
            or (swarm["demand_pct_max"] or 0.0) >= 50.0)


def test_load_says_it_was_limited_by_a_starved_load_generator():
    """The swarm pinned to one CPU with busy competitors there, at nice 19 (its session's autogroup
    too): about 1.5 % of that CPU against one (sched(7): weight 15 against 1024), less than 50
    spectators at 120 Hz need; its receive loop never catches up, and the result says so. How
    little is enough depends on the machine: the test starves it harder until the swarm's own
    counts show it fell behind, and skips with what it measured if they never do."""
    cpu = min(os.sched_getaffinity(0))
    competitor = ["-c", f"import os; os.sched_setaffinity(0, {{{cpu}}}); print('{{}}', flush=True)\nwhile True: pass"]
    busy, measured = [], []
    try:
        for competitors, spectators in STARVING:
            while len(busy) < competitors:
                busy.append(Child(competitor, f"competitor{len(busy)}"))
                busy[-1].expect(lambda o: o == {}, DEADLINE_S, "the competitor's start")
            result = stress.run_scenario("load", _args(spectators=spectators, duration=3.0, still_players=True,
                                                       swarm_schedule={"pin_cpu": cpu, "nice": 19}))
            c, swarm = result["counts"], result["swarm"]
            measured.append(f"{competitors} competitor(s), {spectators} spectators: missed {c['missed_pct']} %, "
                            f"rate median {c['rate_median_hz']} Hz of {c['snapshot_hz']}, demand "
                            f"{swarm['demand_pct_max']} %")
            if _fell_behind(result):
                break
        else:
            pytest.skip("the swarm kept up however it was starved here: " + "; ".join(measured))
    finally:
        for child in busy:
            child.close()
    assert result["limited_by_load_generator"] is True, (measured, result.get("swarm"))
    assert result["swarm"]["saturated"] == ["swarm0"]
    assert any("limited by the load generator" in f for f in result["findings"])


def test_swarm_only_watches_a_server_started_apart():
    server = Child(["-m", "processes.cli", "stress", "--scenario", "load", "--server-only", "--spectators", "20",
                    "--duration", "2", "--still-players", "--json"], "server_only")
    try:
        endpoint = server.expect(lambda o: "listening" in o, DEADLINE_S, "listening line")["listening"]
        result = stress.run_scenario("load", _args(spectators=20, duration=2.0, target=endpoint))
        served = server.expect(lambda o: o.get("scenario") == "load", 120, "the server side's result")
        assert server.wait(DEADLINE_S) == 0
    finally:
        server.close()
    _clean(result)
    c = result["counts"]
    assert c["target"] == endpoint and c["welcomed"] == 20 and c["goodbye_match_over"] == 20
    assert c["snapshots_received"] > 20 and c["invalid_snapshots"] == 0
    assert result["latency_reference"] == "fastest snapshot" and result["latency_ms"]["n"] > 0
    assert served["ok"], served["problems"]
    assert served["counts"]["spectators_joined"] >= 20 and served["counts"]["gateway_snapshots_published"] > 0
    assert served["gateway_latency_ms"]["n"] > 0  # the server side times its own part; the swarm side cannot
    assert "gateway_latency_ms" not in result
