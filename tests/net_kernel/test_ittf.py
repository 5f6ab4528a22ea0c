"""The ITTF's own checks of a net, applied to the model: the net gauge's tension test."""
from dataclasses import replace

import pytest

from net_kernel.gauge import gauge_depression
from net_kernel.topology import NetSpec, resolution_spec


@pytest.mark.xfail(strict=True, reason="the default top cord (20 N) is too slack for the gauge: under its 100 g the "
                                       "columns below the load are in compression and buckle out of plane (the flat "
                                       "loaded shape, 1.1 mm on 46 x 4 and 2.0 mm on 85 x 8, is unstable), so the "
                                       "cord carries the load nearly alone and sinks 14.9 mm (46 x 4), 19.4 mm "
                                       "(85 x 8); test_a_40_newton_top_cord_meets_the_net_gauge passes")
@pytest.mark.parametrize("cols, rows", [(46, 4), (85, 8)])
def test_the_net_gauge_sinks_the_default_top_by_at_most_one_centimetre(cols, rows):
    depression = gauge_depression(resolution_spec(cols, rows))
    assert depression > 0.0, depression  # the gauge's load pulls the top down, never up
    assert depression <= 0.010, depression  # "maximal 10 mm absinken ... mit 100 Gramm" (net tension rule); ITTF T5


def test_a_40_newton_top_cord_meets_the_net_gauge():
    depression = gauge_depression(resolution_spec(85, 8, replace(NetSpec(), cord_tension=40.0)))
    assert depression > 0.0, depression  # the gauge's load pulls the top down, never up
    # The gauge is a maximum, not a target: a tighter net passes (gauge.GAUGE_LOAD's comment).
    assert depression <= 0.010, depression  # "maximal 10 mm absinken ... mit 100 Gramm" (net tension rule); ITTF T5
