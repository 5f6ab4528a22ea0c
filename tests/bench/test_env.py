"""bench/env.py's batched figures at a tiny size: the report's structure and its shares (no
timing asserts: the steps per second are the benchmark's to report)."""
import pytest

from bench.env import batched_steps_per_second


@pytest.mark.parametrize("net", ["rigid", "cloth"])
def test_the_batched_figures_split_the_wall_time_and_bound_the_ratio(net):
    result = batched_steps_per_second([2], 0.3, rounds=2, net=net)
    assert result["single"] > 0 and result["rounds"] == 2
    row = result["batched"]["2"]
    assert row["steps_per_s"] > 0 and row["ratio"] > 0
    assert row["ratio_range"][0] <= row["ratio"] <= row["ratio_range"][1]  # the median of the turns' ratios
    assert 0.0 < row["compiled_share"] <= 1.0 and 0.0 <= row["decisions_share"] <= 1.0
    assert 0.0 <= row["net_share"] <= 1.0 and (row["net_share"] > 0.0) == (net == "cloth")
    assert row["compiled_share"] + row["decisions_share"] + row["net_share"] <= 1.0  # parts of one wall time
    assert row["compiled_alone_ratio"] >= row["ratio"]  # the compiled call is part of the step
