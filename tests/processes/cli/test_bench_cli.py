"""`pingpong bench accuracy|effects|ringdown --quick`, smoke-run as subprocesses, as every command is; no timing asserts."""
import json
import math
import subprocess
import sys
from pathlib import Path

from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[3]
# s: a warm numba cache runs each in a few seconds; a cold one compiles the study's loops and
# every toggled scene's tick first (about 15 s each on a loaded 2-core machine).


def pingpong(*args):
    return subprocess.run([sys.executable, "-m", "processes", "bench", *args], capture_output=True, text=True,
                          timeout=DEADLINE_S, stdin=subprocess.DEVNULL, cwd=ROOT)


def test_bench_accuracy_quick_json_and_plot(tmp_path):
    png = tmp_path / "accuracy.png"
    done = pingpong("accuracy", "--quick", "--json", "--png", str(png))
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert png.stat().st_size > 10_000  # a rendered figure, not an empty file
    labels = {row["label"] for row in result["rows"]}
    assert {"explicit_euler", "semi_implicit_euler", "verlet", "rk4", "dopri5 tick 1 ms"} <= labels
    assert result["compile_seconds"] > 0.0  # compiling or loading the kernels from the cache takes time
    timed = [row for row in result["rows"] if "wall_s_per_sim_s" in row]
    assert timed and all(row["wall_s_per_sim_s"] > 0.0 for row in timed)
    # Every shot bounced twice in the reference, and the reference converged.
    for check in result["reference"]["shots"].values():
        assert len(check["bounces"]) >= 2
        assert check["landing_diff_m"] < 1e-8  # two reference tolerances agree far below the engine's errors
    assert set(result["recommendation"]) == {"full match", "precise shot analysis", "stress"}
    assert all(math.isfinite(v["us_per_tick"]) for v in result["through_step_1ms"].values())


def test_bench_accuracy_human_output():
    done = pingpong("accuracy", "--quick")
    assert done.returncode == 0, done.stderr
    assert "verlet" in done.stdout and "Pareto" not in done.stderr
    assert "full match" in done.stdout


def test_bench_effects_quick_json():
    done = pingpong("effects", "--quick", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    rows = {row["effect"]: row for row in result["effects"]}
    assert rows["drag"]["available"] and rows["drag"]["ratio"] > 0.0
    assert rows["drag"]["compiled_out"] is True  # the scene without drag types it None
    assert rows["bats"]["compiled_out"] is True
    assert rows["recording"]["available"] is False  # reported as not available, never faked
    assert result["absent_check"]["aa_ratio"] > 0.0


def test_bench_effects_human_output():
    done = pingpong("effects", "--quick")
    assert done.returncode == 0, done.stderr
    assert "absent costs nothing" in done.stdout


def test_bench_ringdown_quick_json():
    done = pingpong("ringdown", "--quick", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert set(result["nets"]) == {"hanging", "tied", "hanging_air"}
    assert result["nets"]["hanging"]["air_damping_per_s"] == 5.0  # NetSpec.air_damping, the chosen value
    assert result["nets"]["hanging_air"]["air_damping_per_s"] == 0.2  # topology.AIR_DAMPING_PHYSICAL
    for name, net in result["nets"].items():
        for shot in net["shots"]:
            if name != "hanging_air":  # the air alone rings for about a minute: --quick stops it awake
                assert shot["sleep_s"] is not None and shot["sleep_s"] > 0.0  # every struck net fell asleep
            # stepped by the full kernel or held in the linear tail on every tick until asleep or stopped
            assert shot["awake_ticks"] + shot["tail_ticks"] == round(shot["stepped_s"] / result["dt_s"])
            assert shot["net_cpu_s"] > 0.0
            assert 0.0 < shot["energy_absorbed_J"] <= shot["energy_in_J"]  # the net takes energy, never gives
            assert shot["peak_deflection_m"] > 0.0
    compare = result["air_against_chosen"]
    assert compare["air_damping_per_s"] == [5.0, 0.2] and compare["shots"] == 2
    # The weaker damping keeps the net awake for at least as long as the chosen one does.
    assert compare["awake_ticks_ratio"] >= 1.0


def test_bench_ringdown_human_output():
    done = pingpong("ringdown", "--quick")
    assert done.returncode == 0, done.stderr
    assert "hanging_air" in done.stdout and "air drag alone (0.2/s) against the chosen 5/s" in done.stdout
