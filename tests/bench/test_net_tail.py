"""bench/net_tail.py: the accuracy study of the net's cheaper paths, run small through `pingpong bench net-tail`."""
import dataclasses
import json
import subprocess
import sys

from bench.net_tail import ENERGIES, NUDGE, paths
from net_kernel import NetSpec
from tests.waits import DEADLINE_S


def test_the_quick_study_keeps_the_tail_budget_and_reports_every_strike_on_every_path():
    out = subprocess.run([sys.executable, "-m", "processes", "bench", "net-tail", "--quick", "--json"],
                         capture_output=True, text=True, timeout=DEADLINE_S, check=True)
    result = json.loads(out.stdout)
    tail_energy = next(f.default for f in dataclasses.fields(NetSpec) if f.name == "tail_energy")
    chosen = paths(ENERGIES, tail_energy)
    assert [s["path"] for s in result["summary"]] == [p["path"] for p in chosen]
    assert {(p["kernel_precision"], p["kernel_fma"], p["tail_energy_J"], p["nudge"]) for p in chosen} >= {
        ("float32", False, tail_energy, 0.0), ("float32", True, tail_energy, 0.0), ("float32", True, 0.0, 0.0),
        ("float64", False, 0.0, NUDGE)}  # the float32 paths at the default tail, without it, and a nudged float64
    assert {(p["nudge"], p["tension_nudge"]) for p in chosen} == {(0.0, 0.0), (NUDGE, 0.0), (0.0, NUDGE)}
    assert len(result["rows"]) == len(chosen) * 2  # the quick set: 10 and 30 m/s into the middle, each with a second ball
    for row in result["rows"]:
        if row["tail_energy_J"] > 0:  # the tail holds the ring, on float64 and float32 kernels alike
            assert row["tail_ticks"] > 0 and row["awake_ticks"] < row["reference_awake_ticks"]
        else:
            assert row["tail_ticks"] == 0
        assert row["second_ball"]["same_side"]  # the outcome budget: every path keeps the second ball's side
    default = next(s for s in result["summary"] if s["path"] == f"float64, tail {tail_energy * 1e6:g} uJ")
    # the default's promise (NetSpec.tail_energy): within 50 um of the full kernel, a tenth of a knot's radius
    assert default["worst_knot_error_m"] <= 50e-6 and default["within_budget"]
    assert set(default["worst_over_yardsticks"].values()) == {None}  # nothing over budget: nothing to compare
    reference = result["reference_against_high"]
    for s in result["summary"]:  # every path and the reference, against the float64 kernel at 4x the substeps
        assert s["against_high"]["worst_knot_error_m"] >= s["against_high"]["median_knot_error_m"] > 0
    assert reference["worst_knot_error_m"] > 0 and reference["second_same_side"]
    # A path that steps the ring as the reference does, to the switch, errs as it does against the finer scheme.
    tail = next(s for s in result["summary"] if s["path"] == f"float64, tail {tail_energy * 1e6:g} uJ")["against_high"]
    assert abs(tail["worst_knot_error_m"] - reference["worst_knot_error_m"]) <= 50e-6  # the tail's budget (above)
