"""`pingpong profile-net` smoke run as a subprocess, small net, JSON out."""
import json
import subprocess
import sys

import pytest

from bench.profile_net import parse_knots
from tests.waits import DEADLINE_S


def test_profile_net_smoke():
    done = subprocess.run([sys.executable, "-m", "processes", "profile-net", "--knots", "20x8", "--steps", "2",
                           "--json"], capture_output=True, text=True, timeout=DEADLINE_S)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["knots"] == 160
    assert {(r["path"], r["backend"]) for r in report["results"]} == {
        (path, backend) for path in ("grid", "grid32", "csr") for backend in ("numba", "reference")} | {
        ("grid32_fma", "numba"), ("scatter", "numba")}
    for r in report["results"]:
        assert r["us_per_step"] > 0 and r["msprings_per_s"] > 0 and 0 < r["copy_share"]
        assert r["steps"] == 2 and r["steps_per_call"] == (2 if r["path"].startswith("grid") else 1)
        parallel = r["backend"] == "numba" and r["parallel"]
        assert (r["cpu_us_per_step"] is None) if parallel else r["cpu_us_per_step"] > 0  # serial kernels only
        assert (r["backend"] == "reference") or r["textbook_ratio"] > 0  # the numba rows against the textbook loop
    assert report["copy"]["gb_per_s"] > 0
    passes = report["passes"]
    assert set(passes["passes"]) >= {"springs: one loop a class", "knots: update"}
    assert passes["step_us"] > 0 and passes["divider_floor_us"] > 0 and passes["long_rows"] is None  # 8 rows < 16
    assert passes["spring_floor_us"] > 0 and passes["spring_floor_no_divider_us"] > 0
    assert set(report["vectors"]) == {"grid springs (_horizontal, _bands)", "grid knots (_knots)",
                                      "grid32 springs (_springs_exact)", "grid32 knots (_knots_exact)",
                                      "csr (step_knots_serial)", "textbook scatter (step_knots_scatter)"}
    for name in ("grid32 springs (_springs_exact)", "grid32 knots (_knots_exact)"):
        assert report["vectors"][name]["width"].endswith("/f32")  # float32 lanes
    awake = report["awake_ticks"]
    assert set(awake["us"]) == {"float64", "float32", "float32 fma"} and min(awake["us"].values()) > 0


def test_profile_net_text_and_bad_knots():
    done = subprocess.run([sys.executable, "-m", "processes", "profile-net", "--knots", "12x4", "--steps", "1",
                           "--backend", "numba"], capture_output=True, text=True, timeout=DEADLINE_S)
    assert done.returncode == 0, done.stderr
    assert "Msprings/s" in done.stdout and "of copy" in done.stdout and "x textbook" in done.stdout
    assert "vectorised?" in done.stdout and "the divider's floor" in done.stdout
    assert "grid32_fma" in done.stdout and "awake NetSim tick" in done.stdout
    bad = subprocess.run([sys.executable, "-m", "processes", "profile-net", "--knots", "12by4"],
                         capture_output=True, text=True, timeout=DEADLINE_S)
    assert bad.returncode == 2 and "COLSxROWS" in bad.stderr
    assert parse_knots("184x16") == (184, 16)


def test_tick_costs_small_net():
    from bench.net_tick import tick_costs

    report = tick_costs(sizes=((20, 8),), ticks=2, repeats=1)
    (row,) = report["rows"]
    assert row["knots"] == 160 and row["substeps"] >= 1
    for case in ("awake", "near", "impact"):
        for sweep in ("full", "culled", "netsim"):
            assert row[f"{case}_{sweep}_us"] > 0
    with pytest.raises(ValueError, match="clock"):
        tick_costs(sizes=((20, 8),), ticks=1, repeats=1, clock="cpu")
