"""bench/net_tail.py: the linear tail's accuracy study, run small through `pingpong bench net-tail`."""
import dataclasses
import json
import subprocess
import sys

from bench.net_tail import ENERGIES
from net_kernel import NetSpec
from tests.waits import DEADLINE_S


def test_the_quick_tail_study_keeps_the_budget_and_reports_every_strike():
    out = subprocess.run([sys.executable, "-m", "processes", "bench", "net-tail", "--quick", "--json"],
                         capture_output=True, text=True, timeout=DEADLINE_S, check=True)
    result = json.loads(out.stdout)
    assert {r["tail_energy_J"] for r in result["rows"]} == set(ENERGIES)
    assert len(result["rows"]) == len(ENERGIES) * 2  # the quick set: 10 and 30 m/s into the middle, each with a second ball
    for row in result["rows"]:
        assert row["tail_ticks"] > 0 and row["awake_ticks"] < row["reference_awake_ticks"]
        assert row["second_ball"]["same_side"]
    tail_energy = next(f.default for f in dataclasses.fields(NetSpec) if f.name == "tail_energy")
    default = next(s for s in result["summary"] if s["tail_energy_J"] == tail_energy)
    # the default's promise (NetSpec.tail_energy): within 50 um of the full kernel, a tenth of a knot's radius
    assert default["worst_knot_error_m"] <= 50e-6 and default["within_budget"]
