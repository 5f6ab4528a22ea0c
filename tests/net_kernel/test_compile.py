"""A net worker compiles every kernel before it says ready: a match then compiles nothing."""
import json
import subprocess
import sys

from tests.waits import DEADLINE_S

# In a fresh interpreter, so no earlier test has loaded a kernel the warm-up forgot: the set of
# signatures each numba dispatcher holds after compile_kernels, then after a match's worth of net
# ticks (a ball through the net, ticks without it, free ticks until the net's linear tail takes it
# over and it sleeps, the probe of a sleeping net, a touch that wakes it).
_SCRIPT = r"""
import json
import numpy as np
from numba.core.registry import CPUDispatcher
from net_kernel import NetSim, build_topology, kernels
from net_kernel.sim import compile_kernels
from net_kernel.topology import resolution_spec

def signatures():  # every dispatcher of every module of the kernels package, private ones too
    return {module.__name__ + "." + name: sorted(map(str, d.signatures))
            for module in (kernels.contact, kernels.csr, kernels.grid, kernels.implicit, kernels.modal)
            for name, d in vars(module).items() if isinstance(d, CPUDispatcher)}

topo = build_topology(resolution_spec(46, 4))
compile_kernels(topo, 1e-3)
before = signatures()
sim = NetSim(topo, 1e-3)
knot = topo.knot_pos[2 * 46 + 20]  # aim at a knot: a 46 x 4 net's cells are wider than the ball
pos, vel = knot + [-0.1, 0.0, 0.0], np.array([12.0, 0.0, 0.0])
for _ in range(40):  # the ball into the net and back out (the net's impulses bend it)
    contact = sim.step(pos, vel)
    pos = pos + vel * 1e-3 + contact.offset
    vel = vel + contact.impulse / 2.7e-3
sim.step()
for _ in range(20):
    sim.step_free(500)
asleep = sim.sleeping and sim.tail_ticks > 0
sim.step(knot + [-0.3, 0.0, 0.0], np.zeros(3))  # a sleeping net's box test, no probe
sim.step(knot + [-0.021, 0.0, 0.0], np.array([5.0, 0.0, 0.0]))  # the probe, then the touch wakes it
print(json.dumps({"before": before, "after": signatures(), "asleep": asleep, "woken": not sim.sleeping}))
"""


def test_a_match_compiles_nothing_after_compile_kernels():
    out = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, timeout=DEADLINE_S, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["asleep"] and result["woken"]  # the run went through every path it means to
    new = {name: sorted(set(sigs) - set(result["before"].get(name, []))) for name, sigs in result["after"].items()}
    assert not any(new.values()), {name: sigs for name, sigs in new.items() if sigs}
