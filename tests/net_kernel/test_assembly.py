"""The vector width of a kernel's loops is read from its assembly (net_kernel/assembly.py)."""
import platform

import numpy as np
import pytest

from net_kernel.assembly import innermost_loops, vector_report
from net_kernel.kernels import grid

_LISTING = """\
kernel:
\tvmovupd\t(%rax), %ymm0
.LBB0_1:
\tvmovupd\t(%rdi,%rcx,8), %zmm1
\tvaddpd\t%zmm1, %zmm0, %zmm0
\tvsqrtpd\t%zmm0, %zmm2
\taddq\t$8, %rcx
\tjne\t.LBB0_1
.LBB0_2:
\tvaddsd\t%xmm1, %xmm0, %xmm0
.LBB0_3:
\tvmulsd\t(%rdi), %xmm0, %xmm0
\tvdivsd\t%xmm1, %xmm0, %xmm0
\tjne\t.LBB0_3
\tvmulpd\t%ymm1, %ymm0, %ymm0
\tjmp\t.LBB0_2
\tret
"""


def test_innermost_loops_are_counted_by_register_width():
    loops = innermost_loops(_LISTING)
    # .LBB0_1 (zmm) and .LBB0_3 (scalar) are innermost; .LBB0_2 holds .LBB0_3, so it is not.
    assert [dict(w) for w in loops] == [{"zmm": 2}, {"scalar": 2}]


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="reads x86-64 assembly")
def test_the_grid_spring_loop_is_packed():
    rows, cols = 4, 12
    state = np.zeros((2, 3, rows, cols))
    params = np.ones((grid.GRID_CLASSES, 3))
    report = vector_report(grid._grid_block, (state, np.ones((rows, cols)), params, grid.grid_work(rows, cols), 9.81,
                                              5.0, 1e-5, 0, rows))
    assert report["lanes"] >= 2 and report["packed_ops"] > 0  # x86-64 has at least SSE2's 2 float64 lanes
    assert report["scalar_loops"] < report["loops"]
