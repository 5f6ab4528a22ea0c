"""`pingpong bench net-resolution --quick`, smoke-run as a subprocess, as every command is; no timing asserts."""
import json
import subprocess
import sys
from pathlib import Path

from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[3]
# s: the net kernels come from numba's cache in a few seconds; a cold cache compiles them first.


def pingpong(*args):
    return subprocess.run([sys.executable, "-m", "processes", "bench", "net-resolution", *args], capture_output=True,
                          text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL, cwd=ROOT)


def test_bench_net_resolution_quick_json():
    done = pingpong("--quick", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    rows = {f"{r['cols']}x{r['rows']}": r for r in result["rows"]}
    assert list(rows) == ["46x4", "70x7", "92x8"] and result["reference"] == "92x8"
    ref = rows["92x8"]
    assert ref["errors"]["exit_velocity_error_max"] == 0.0  # the reference against itself
    assert ref["errors"]["outcome_changes"] == 0
    # The same physical net on every grid (resolution_spec): one prestress and areal density.
    for key in ("mesh_prestress", "areal_density", "cord_tension"):
        values = [r["continuum"][key] for r in rows.values()]
        assert max(values) - min(values) <= 1e-12 * max(values), key
    # 46 x 4's cells (41 x 51 mm, diagonal 65 mm) let the 40 mm ball through; 92 x 8's (30 mm) do not.
    assert rows["46x4"]["geometry"]["ball_fits_through"] and not ref["geometry"]["ball_fits_through"]
    assert rows["46x4"]["stress_through"] > 0 and ref["stress_through"] == 0  # 20-60 m/s at a cell's middle
    assert result["floor"]["shift_m"] > 0.0 and result["floor"]["exit_velocity_error_median"] >= 0.0
    for row in rows.values():
        assert len(row["impacts"]) == 3 and all(imp["touched"] for imp in row["impacts"])
        assert row["cpu_ms_per_impact"] > 0.0 and row["substeps"] >= 1
        assert row["ring_downs"] and row["ring_downs"][0]["ticks"] > 0
    # Fewer knots and substeps, less work per awake tick: a ratio in the same run, not a time.
    assert rows["46x4"]["knots"] * rows["46x4"]["substeps"] < ref["knots"] * ref["substeps"]


def test_bench_net_resolution_human_output_and_bad_sizes():
    done = pingpong("--quick")
    assert done.returncode == 0, done.stderr
    assert "92x8" in done.stdout and "outcome changes" in done.stdout
    bad = pingpong("--sizes", "70x7,92")
    assert bad.returncode != 0 and "COLSxROWS" in bad.stderr
