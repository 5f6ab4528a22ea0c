"""The cloth net's knots on the wire: offsets from the rest grid, within half a step, clamped and
counted beyond the range (processes.network.wire.knots)."""
import numpy as np
import pytest

from processes.network import wire
from processes.network.wire import Kind, decode


def test_a_nets_knots_round_trip_within_half_a_step():
    """Knots 85 x 8 (scenes/match.toml's grid) moved up to 5 cm: two messages, and every
    coordinate back within NET_STEP_M / 2 (round to nearest) of what was sent."""
    cols, rows, width, height = 85, 8, 1.83, 0.1525
    rest = wire.net_rest(cols, rows, width, height)
    knots = rest + np.random.default_rng(3).uniform(-0.05, 0.05, rest.shape)
    messages, clamped = wire.net_messages(knots, cols=cols, rows=rows, width=width, height=height, asleep=True,
                                          tick=77)
    assert clamped == 0 and len(messages) == 2 and {len(m) for m in messages} == {wire.SIZES[Kind.NET]}
    back = np.full_like(knots, np.nan)
    for data in messages:
        message = decode(data)
        assert message.tick == 77 and message["asleep"] == 1
        wire.net_knots(message, back)
    np.testing.assert_allclose(back, knots, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # rounding, + float error


def test_a_knot_beyond_the_wires_range_is_clamped_and_counted():
    rest = wire.net_rest(4, 2, 1.0, 0.2)
    knots = rest.copy()
    knots[5, 0] = 0.5  # 50,000 steps: beyond +-32767
    (data,), clamped = wire.net_messages(knots, cols=4, rows=2, width=1.0, height=0.2, asleep=False, tick=1)
    assert clamped == 1
    back = np.zeros_like(knots)
    wire.net_knots(decode(data), back)
    assert back[5, 0] == pytest.approx(wire.NET_MAX_OFFSET * wire.NET_STEP_M, abs=1e-12)  # the range's edge


def test_the_wires_rest_grid_carries_the_nets_built_and_hanging_shapes():
    from net_kernel import build_topology
    from net_kernel.topology import NetSpec

    spec = NetSpec(cols=85, rows=8)
    rest = wire.net_rest(spec.cols, spec.rows, spec.width, spec.height)
    topo = build_topology(spec)
    # the same knot order and columns, bit for bit; the built net's rows start at its hem gap and
    # it rests in its hanging shape, which the offsets carry
    np.testing.assert_array_equal(rest[:, :2], topo.knot_pos[:, :2])
    for shape in (topo.knot_pos, topo.rest_pos):
        messages, clamped = wire.net_messages(shape, cols=spec.cols, rows=spec.rows, width=spec.width,
                                              height=spec.height, asleep=True, tick=0)
        back = np.zeros_like(shape)
        for data in messages:
            wire.net_knots(decode(data), back)
        assert clamped == 0
        np.testing.assert_allclose(back, shape, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # half a 0.01 mm step
