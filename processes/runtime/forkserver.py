"""Imported by the forkserver the supervisor starts its workers from (its preload), and only there:
the forkserver ignores SIGTERM, as the workers do (runtime.control.worker_main).

A SIGTERM to the whole process group (systemd's stop, `kill -- -PGID`) reaches the forkserver
too. Dead, it would orphan the workers it forked, which take a changed parent for the
supervisor's death and stop at once, before the supervisor could stop them in order (the
gateway's goodbyes and last counters). The supervisor's own SIGTERM handling stops the run; the
forkserver ends when the supervisor does (its control pipe closes).
"""
import signal

signal.signal(signal.SIGTERM, signal.SIG_IGN)
