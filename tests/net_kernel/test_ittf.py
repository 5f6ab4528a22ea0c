"""The ITTF's own checks of a net, applied to the model: the net gauge's tension test."""
import pytest

from net_kernel.topology import gauge_depression, resolution_spec


@pytest.mark.parametrize("cols, rows", [(46, 4), (85, 8)])
def test_the_net_gauge_depresses_the_top_by_one_centimetre(cols, rows):
    depression = gauge_depression(resolution_spec(cols, rows))
    # ITTF net gauge (Technical Leaflet T5), as umpires apply it: 100 g at the middle of the top
    # may depress it by 1 cm (topology.GAUGE_LOAD's source); 8-10 mm leaves 2 mm for the grid.
    assert 0.008 <= depression <= 0.010, depression
