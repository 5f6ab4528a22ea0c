"""The net's dampers against the analytic decay: one spring-damper, and a small net's air damping."""
import math

import numpy as np

from net_kernel import NetSim, build_topology, grid_spec, make_topology
from net_kernel.topology import NetSpec


def test_one_spring_damper_decays_as_the_damped_oscillator():
    mass, stiffness, dashpot, x0 = 1e-3, 10.0, 2e-3, 1e-4  # kg, N/m, N s/m, m: 100 rad/s, zeta = 0.01
    rest = 0.1
    knot_pos = np.array([[0.0, 0.0, 0.0], [0.0, rest + x0, 0.0]])
    topo = make_topology(knot_pos, np.full(2, mass), np.array([True, False]), np.array([[0, 1]]), np.array([rest]),
                         np.array([stiffness]), np.array([dashpot]), spec=NetSpec(gravity=0.0, air_damping=0.0))
    sim = NetSim(topo, 1e-3, substeps=10)  # the match's tick; 10 substeps of h = 0.1 ms
    h = sim.h
    omega = math.sqrt(stiffness / mass)
    zeta = dashpot / (2.0 * math.sqrt(stiffness * mass))
    omega_d = omega * math.sqrt(1.0 - zeta * zeta)
    t = np.arange(1, 1001) * 1e-3
    x = np.empty(t.size)
    for k in range(t.size):
        sim.step()
        x[k] = sim.knot_pos[1, 1] - rest
    phase = omega_d * t
    exact = x0 * np.exp(-zeta * omega * t) * (np.cos(phase) + zeta / math.sqrt(1.0 - zeta * zeta) * np.sin(phase))
    # Symplectic Euler's global error is first order: its phase drifts by (omega h)^2 / 24 a radian
    # and its decay rate is off by h g / 2 (Hairer, Lubich & Wanner, Geometric Numerical Integration,
    # 2nd ed., 2006, I.1 and IX.3), half a step's lag, 5e-3 of the amplitude over 100 rad; 1 %.
    assert not sim.sleeping
    assert np.abs(x - exact).max() < 0.01 * x0, np.abs(x - exact).max() / x0


def test_a_small_nets_air_damping_decays_every_mode_at_half_its_rate():
    # Mass-proportional damping g decays every mode of the linearised net as exp(-g t / 2) and
    # shifts its frequency by g^2 / (8 w^2) only (Rayleigh, The Theory of Sound, 1877, 1.97): the
    # damped net's motion times exp(g t / 2) is the undamped net's.
    g = 0.5  # 1/s
    # the kernel's own damping: no linear tail (tests/net_kernel/test_tail.py checks the tail's)
    nets = {air: build_topology(grid_spec(12, 4, spring_c=0.0, air_damping=air, gravity=0.0, tail_energy=0.0))
            for air in (0.0, g)}
    sims = {air: NetSim(topo, 1e-3) for air, topo in nets.items()}
    topo = nets[0.0]
    free = topo.knot_inv_mass > 0
    y, z = topo.rest_pos[:, 1], topo.rest_pos[:, 2]
    shape = np.sin(np.pi * (y / topo.spec.width + 0.5)) * np.sin(np.pi * z / topo.spec.height)
    ticks = 4000  # 4 s: the amplitude falls to 1/e
    for sim in sims.values():
        # 10 um out of the plane: the linear regime (the stretch that an out-of-plane displacement w
        # adds, k_s (w / a)^2 against the pretension's T / a, shifts the frequency by 2e-6 here).
        sim.knot_pos[:, 0] += 1e-5 * shape * free
        sim.quiet_ticks = -2 * ticks  # the sleep rule is not under test: no knot here outruns SLEEP_SPEED
    h = sims[g].h
    worst = 0.0
    scale = 1e-5
    for tick in range(1, ticks + 1):
        for sim in sims.values():
            sim.step()
        # the scheme's per-step velocity factor (1 - h g) is det of its amplification matrix: the
        # amplitude decays by its square root a step
        undo = (1.0 - h * g) ** (-0.5 * tick * sims[g].substeps)
        worst = max(worst, float(np.abs(sims[g].knot_pos[:, 0] * undo - sims[0.0].knot_pos[:, 0]).max()))
    assert not sims[g].sleeping and not sims[0.0].sleeping
    # The frequency shift drifts the phase by g^2 t / (8 w), 0.008 rad over 4 s for the net's
    # fundamental (2.4 Hz): 1 % of the amplitude; 3 % leaves room for its slower hem modes.
    assert worst < 0.03 * scale, worst / scale
