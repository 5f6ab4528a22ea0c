"""The ITTF's own checks of a net, applied to the model: the net gauge's tension test."""
import pytest

from net_kernel.topology import gauge_depression, resolution_spec


@pytest.mark.xfail(strict=True, reason="the model's springs bear compression: the columns under the gauge's load carry "
                                       "it to the hem (85 x 8: 1.9 mm in the explicit solver, and the implicit settle "
                                       "buckles them); with threads that go slack under compression (a select in every "
                                       "kernel and twin), 40 N of top cord gives 9.9 mm on 46 x 4 and 85 x 8, but 60 m/s "
                                       "shots then go through the match net (85 x 8; 184 x 16 too): the ball touches "
                                       "knots, not threads, so knots slide round it to its back and the springs from "
                                       "them to the knots in front, chords through the ball, push it on; and one-sided "
                                       "springs pump the undamped net's energy at 0.9 h_max")
@pytest.mark.parametrize("cols, rows", [(46, 4), (85, 8)])
def test_the_net_gauge_depresses_the_top_by_one_centimetre(cols, rows):
    depression = gauge_depression(resolution_spec(cols, rows))
    # ITTF net gauge (Technical Leaflet T5), as umpires apply it: 100 g at the middle of the top
    # may depress it by 1 cm (topology.GAUGE_LOAD's source); 8-10 mm leaves 2 mm for the grid.
    assert 0.008 <= depression <= 0.010, depression
