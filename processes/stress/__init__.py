"""`pingpong stress`: a real server and a swarm of client processes, scenario by scenario, with a report.

Each scenario (scenarios/) starts its own server (server: the Supervisor with its gateway and
physics workers, as `pingpong serve` runs it, plus a tick clock) and client processes (swarm/,
many ZeroMQ clients each; bots are `pingpong join --bot`), all on 127.0.0.1, every wait bounded,
every process killed and reaped at the end whatever happened (harness). probes reads /proc,
result holds what each scenario checks, report turns the results into what a user reads.

Invariants become `problems` (empty when the scenario passes). Numbers that depend on the machine
(rates, latency, jitter, CPU) are reported, never asserted.
"""
from processes.stress.command import SCENARIOS, add_arguments, stress_command

__all__ = ["SCENARIOS", "add_arguments", "stress_command"]
