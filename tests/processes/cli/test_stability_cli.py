"""`pingpong stability` on the stiff-net cases: one JSON object per case, the fixed step refused by name."""
import json
import subprocess
import sys

from tests.waits import DEADLINE_S


def test_stiff_net_rows_over_json():
    done = subprocess.run([sys.executable, "-m", "processes.cli", "stability", "--case",
                           "stiff net: 100x k_s and k_d, tick 10.0x h_max", "--json"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    rows = {row["case"].rsplit(", ", 1)[1]: row for row in map(json.loads, done.stdout.splitlines())}
    assert set(rows) == {"substepped", "fixed", "implicit"}
    for row in rows.values():
        assert set(row) >= {"finite", "tunnelled", "max_penetration_m", "energy_gain", "energy_change", "max_abs_state"}
    assert rows["fixed"]["result"].startswith("refused: substep h = ")
    assert "stability bound h_max" in rows["fixed"]["result"]
    for mode in ("substepped", "implicit"):
        assert rows[mode]["result"] == "stable" and rows[mode]["finite"]
        assert rows[mode]["energy_change"] < 0.0 and rows[mode]["energy_gain"] <= 0.10
    assert rows["substepped"]["integrator"] == "net explicit x12"  # 10 h_max / (0.9 h_max) rounded up
    assert rows["implicit"]["energy_gain"] <= 1e-9
