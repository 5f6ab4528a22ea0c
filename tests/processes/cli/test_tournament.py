"""Many matches as tasks: the local pool and Ray give the same records, resume, retries, sweeps."""
import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from scipy.stats import binomtest

from engine.physics.scene import load_scene
from engine.play.match import match_record
from processes.cli import main, standings, sweep
from processes.cli.tournament import MATCHES_FILE, pairs_of, plan, run_tasks
from tests.helpers.commands import ctrl_c_able
from tests.waits import DEADLINE_S

ray = pytest.importorskip("ray")

TICKS = 30_000  # 30 s of play: a few rallies, ~0.2 s a match
SEEDS = 2


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray instance for the module's tests (its start-up is paid once)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def tasks():
    """The small tournament; its kernels compiled here first, so the pool's processes and Ray's
    workers load them from numba's cache instead of each compiling them at once."""
    match_record(load_scene("match_rigid"), 0, "pro", "novice", best_of=1, max_ticks=2)
    return plan(load_scene("match_rigid"), pairs_of(["pro", "novice"]), SEEDS, best_of=1, max_ticks=TICKS)


def _lines(path):
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_local_pool_and_ray_write_the_same_records(tmp_path, tasks, local_ray):
    local = run_tasks(tasks, tmp_path / "local", "local", 2, show_progress=False)
    on_ray = run_tasks(tasks, tmp_path / "ray", "ray", 2, show_progress=False)
    assert local.played == on_ray.played == len(tasks) == 4
    hashes = {name: {(r["a"], r["b"], r["seed"]): r["record_hash"] for r in _lines(tmp_path / name / MATCHES_FILE)}
              for name in ("local", "ray")}
    assert hashes["local"] == hashes["ray"] and len(hashes["local"]) == 4
    first = tasks[0]
    in_process = match_record(first.scene, first.seed, first.a, first.b, first.best_of, first.max_ticks)
    assert hashes["local"][(first.a, first.b, first.seed)] == in_process["record_hash"]


def test_a_bot_plays_the_same_records_on_the_pool_and_on_ray_from_the_source_it_was_planned_with(tmp_path,
                                                                                                 local_ray):
    bot = tmp_path / "my_block.py"
    bot.write_text((Path(__file__).resolve().parents[3] / "examples" / "block.py").read_text())
    spec = f"{bot}:Block"
    bot_tasks = plan(load_scene("match_rigid"), pairs_of([spec, "novice"]), 1, best_of=1, max_ticks=TICKS // 3)
    in_process = match_record(bot_tasks[0].scene, 0, spec, "novice", 1, TICKS // 3)
    bot.unlink()  # the workers get the bot's source with their task, not from this file
    local = run_tasks(bot_tasks, tmp_path / "local", "local", 2, show_progress=False)
    on_ray = run_tasks(bot_tasks, tmp_path / "ray", "ray", 2, show_progress=False)
    assert local.failure is None and on_ray.failure is None and local.played == on_ray.played == 2
    records = {name: {(r["a"], r["b"]): r["record_hash"] for r in _lines(tmp_path / name / MATCHES_FILE)}
               for name in ("local", "ray")}
    assert records["local"] == records["ray"]
    assert records["local"][(spec, "novice")] == in_process["record_hash"]


def test_resume_skips_finished_matches_and_a_cut_line(tmp_path, tasks, local_ray):
    first = run_tasks(tasks[:2], tmp_path, "ray", 2, show_progress=False)
    assert first.played == 2
    with open(tmp_path / MATCHES_FILE, "a") as log:
        log.write('{"a": "pro", "b": "nov')  # a line cut by a crash mid-write
    again = run_tasks(tasks, tmp_path, "ray", 2, show_progress=False)
    assert (again.skipped, again.played) == (2, 2)
    lines = (tmp_path / MATCHES_FILE).read_text().splitlines()
    records = [json.loads(line) for line in lines if line.endswith("}")]
    assert len(lines) == 5 and len(records) == 4
    assert len({(r["a"], r["b"], r["seed"]) for r in records}) == 4


def test_a_killed_ray_worker_is_retried_and_its_match_recorded_once(tmp_path, tasks, local_ray):
    marker = tmp_path / "killed-once"
    report = run_tasks(tasks[:1], tmp_path, "ray", 2, show_progress=False, crash_marker=str(marker))
    assert marker.exists()  # the first attempt ran and SIGKILLed its worker
    assert report.played == 1 and len(_lines(tmp_path / MATCHES_FILE)) == 1


def test_a_killed_pool_process_stops_the_run_and_a_rerun_plays_its_match(tmp_path, tasks):
    marker = tmp_path / "killed-once"
    report = run_tasks(tasks[:1], tmp_path, "local", 1, show_progress=False, crash_marker=str(marker))
    assert marker.exists() and report.played == 0 and "BrokenProcessPool" in report.failure
    again = run_tasks(tasks[:1], tmp_path, "local", 1, show_progress=False, crash_marker=str(marker))
    assert again.failure is None and again.played == 1 and len(_lines(tmp_path / MATCHES_FILE)) == 1


def test_sweep_over_two_values_of_one_key(tmp_path, local_ray, capsys):
    code = main(["sweep", "match", "--set", "match.ai_hz=50,100", "--seeds", "1", "--best-of", "1",
                 "--ticks", str(TICKS), "--cluster", "ray", "--out", str(tmp_path), "--json"])
    assert code == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    cells = [line for line in lines if "cell" in line]
    assert [c["cell"] for c in cells] == [{"match.ai_hz": 50}, {"match.ai_hz": 100}]
    assert all(c["matches"] == 1 and c["realtime_factor"] > 0 for c in cells)
    assert len(_lines(tmp_path / "cells.jsonl")) == 2 and (tmp_path / "sweep.png").stat().st_size > 0
    hashes = {r["cell"]["match.ai_hz"]: r["scene_hash"] for r in _lines(tmp_path / MATCHES_FILE)}
    assert hashes[50] != hashes[100]


@pytest.mark.parametrize("setting, message", [
    ("match.nope=1,2", "match.nope: unknown key; allowed here: best_of"),
    ("match.ai_hz=5,100", "match.ai_hz: must be in [10.0, 2000.0], got 5.0"),
    ("integrator=verlet,leapfrog", "integrator: must be one of"),
    ("dt.x=1", "dt: is a value, not a table"),
    ("match.ai_hz", "--set: must be KEY=V1,V2"),
])
def test_bad_set_keys_and_values_are_refused_with_the_validators_message(tmp_path, capsys, setting, message):
    assert main(["sweep", "match", "--set", setting, "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / MATCHES_FILE).exists()  # refused before anything ran


def _tournament_args(out, seeds: int) -> list[str]:
    return ["tournament", "--scene", "match_rigid", "--skills", "pro,novice", "--seeds", str(seeds), "--best-of", "1",
            "--ticks", str(TICKS), "--workers", "1", "--out", str(out)]


def test_tournament_cli_on_the_local_pool_and_ctrl_c_keeps_the_finished(tmp_path):
    proc = subprocess.Popen(ctrl_c_able(*_tournament_args(tmp_path, 40)), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    log = tmp_path / MATCHES_FILE
    try:
        deadline = time.monotonic() + DEADLINE_S
        while not (log.exists() and log.read_text().count("\n") >= 1):
            assert time.monotonic() < deadline and proc.poll() is None, "no match finished"
            time.sleep(0.05)  # polling a file with a deadline, not a sleep used as a handshake
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    assert proc.returncode == 130 and "a rerun with the same --out plays the rest" in err
    kept = {(r["a"], r["b"], r["seed"]) for r in _lines(log)}
    assert 1 <= len(kept) < 80
    done = subprocess.run([sys.executable, "-m", "processes", *_tournament_args(tmp_path, 2), "--json"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    planned = {(a, b, seed) for a, b in (("pro", "novice"), ("novice", "pro")) for seed in range(2)}
    assert summary["matches"] == 4 and summary["skipped"] == len(kept & planned)
    assert summary["matches_per_minute"] > 0 and (tmp_path / "standings.json").exists()


@pytest.mark.parametrize("text, values", [
    ("50,100,250", [50, 100, 250]),
    ("verlet,rk4", ["verlet", "rk4"]),
    ("[92,8],[184,16]", [[92, 8], [184, 16]]),
    ("0.5,true", [0.5, True]),
])
def test_set_values_read_as_toml_or_bare_words(text, values):
    assert sweep.parse_values(text) == values


def test_a_swept_net_resolution_is_validated_as_the_files_own_key():
    scene = load_scene("match", overrides={"net.resolution": [92, 8]})
    assert (scene.cloth.cols, scene.cloth.rows) == (92, 8)


def test_wilson_interval_matches_scipy():
    low, high = standings.wilson(7, 8)
    reference = binomtest(7, 8).proportion_ci(method="wilson")
    assert (low, high) == pytest.approx((reference.low, reference.high), abs=1e-12)  # same formula


def test_elo_of_two_profiles_is_their_odds_on_the_elo_scale():
    records = [{"a": "pro", "b": "club", "winner": w} for w in ("a", "a", "b", "a")]
    ratings = standings.elo(records, ["pro", "club"])
    # Two players: the Bradley-Terry fit's odds are the win ratio (3 + 0.5 prior) / (1 + 0.5).
    gap = ratings["pro"]["elo"] - ratings["club"]["elo"]
    assert gap == pytest.approx(400 * math.log10(3.5 / 1.5), abs=1e-6)
    assert ratings["pro"]["low"] <= ratings["pro"]["elo"] <= ratings["pro"]["high"]


@pytest.mark.parametrize("cluster", ["local", "ray"])
def test_a_bot_no_interrupt_reaches_is_abandoned_and_the_tournament_finishes(tmp_path, tasks, cluster, request):
    # The bot blocks SIGALRM and sleeps: the wall-clock guard cannot stop it, its pool process is
    # ended by the watchdog with the match recorded as it stood (stopped, the bot named), and the
    # other matches (one was running beside it in the broken pool) are played all the same.
    from tests import bots

    if cluster == "ray":
        request.getfixturevalue("local_ray")
    blocking = plan(load_scene("match_rigid"), [(bots.spec("BlocksSignals"), "novice")], 1, best_of=1,
                    max_ticks=TICKS)
    report = run_tasks(blocking + tasks, tmp_path, cluster, 2, show_progress=False)
    assert report.failure is None and report.played == len(tasks) + 1
    records = {(r["a"], r["seed"]): r for r in _lines(tmp_path / MATCHES_FILE)}
    given_up = records[(bots.spec("BlocksSignals"), 0)]
    assert given_up["stopped"] and given_up["winner"] is None and given_up["ticks"] > 0
    assert "bot BlocksSignals (bots.py) (player A) has not returned from act()" in given_up["abandoned"]
    assert sum("abandoned" in r for r in records.values()) == 1


def test_tables_and_the_plot_name_a_bot_by_its_class_and_file_whole(tmp_path, capsys):
    from processes.cli import standings

    a, b = "/some/where/examples/attack.py:Attack", "/else/where/attack.py:Attack"
    assert standings.labels(["pro", "/x/block.py:Block"]) == {"pro": "pro", "/x/block.py:Block": "Block (block.py)"}
    assert standings.labels([a, b]) == {a: a, b: b}  # the same short name twice: the whole specs
    profiles = ["pro", "/x/block.py:Block"]
    records = [{"a": "pro", "b": profiles[1], "winner": "a", "points": [11, 3], "mean_rally_shots": 3.0,
                "reasons": {"a": {"net": 3}, "b": {"out_long": 11}}, "sim_seconds": 60.0, "wall_seconds": 1.0}] * 3
    table = standings.standings(records, profiles)
    standings.print_standings(table)
    assert "Block (block.py)" in capsys.readouterr().out
    standings.heatmap_png(table["matrix"], tmp_path / "winrate.png", "t")
    assert (tmp_path / "winrate.png").stat().st_size > 0
