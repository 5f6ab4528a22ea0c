"""The ITTF's own checks of a net, applied to the model: the net gauge's tension test."""
from dataclasses import replace

import pytest

from net_kernel.gauge import gauge_depression
from net_kernel.topology import NetSpec, resolution_spec


@pytest.mark.parametrize("cols, rows", [(46, 4), (85, 8)])
def test_the_net_gauge_sinks_the_default_top_by_at_most_one_centimetre(cols, rows):
    depression = gauge_depression(resolution_spec(cols, rows))
    assert depression > 0.0, depression  # the gauge's load pulls the top down, never up
    # The gauge is a maximum, not a target: a tighter net passes (gauge.GAUGE_LOAD's comment).
    assert depression <= 0.010, depression  # "maximal 10 mm absinken ... mit 100 Gramm" (net tension rule); ITTF T5


def test_a_20_newton_top_cord_fails_the_net_gauge():
    # Under the gauge's load the columns below it buckle out of plane and the cord carries it nearly
    # alone: the flat loaded shape (2 mm on 85 x 8) is unstable, and a gauge that found it would pass
    # a net twice too slack.
    depression = gauge_depression(resolution_spec(85, 8, replace(NetSpec(), cord_tension=20.0)))
    assert depression > 0.010, depression  # "maximal 10 mm absinken ... mit 100 Gramm" (net tension rule); ITTF T5
