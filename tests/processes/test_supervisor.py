"""Multi-process runs: lockstep equals the in-process reference bit for bit, crashes are survived,
Ctrl-C leaves nothing behind, a scene starts only the workers it needs."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from engine.physics.scene import load_scene, with_overrides
from engine.tools.run import run
from processes.runtime.shm import Arena, leftover_segments
from processes.supervisor import Supervisor, first_difference, workers_for
from processes.runtime.control import STATUS_DTYPE, WorkerState
from tests.helpers.commands import ctrl_c_able
from tests.waits import DEADLINE_S


@pytest.mark.parametrize("name, integrator", [("rally", "verlet"), ("serve", "dopri5"), ("drop", "rk4")])
def test_lockstep_equals_in_process_reference_bit_for_bit(name, integrator, no_leftovers):
    # Thousands of ticks with drag, Magnus, friction, bats, net and resting contact.
    scene = with_overrides(load_scene(name), integrator=integrator)
    result = Supervisor(scene, scene.ticks, "lockstep", trace=True).run()
    reference = run(scene, trace=True)
    assert result.ticks == scene.ticks
    assert first_difference(result.trace, reference.trace) is None
    assert result.events.tobytes() == reference.events.tobytes()


def test_sigkilled_worker_is_restarted_and_the_run_stays_exact(no_leftovers):
    scene = with_overrides(load_scene("serve"), integrator="dopri5")
    result = Supervisor(scene, scene.ticks, "lockstep", trace=True, crash_at_tick=700).run()
    assert result.workers["physics"]["restarts"] == 1
    assert result.ticks == scene.ticks
    assert first_difference(result.trace, run(scene, trace=True).trace) is None


def test_realtime_is_paced_by_the_wall_clock(no_leftovers):
    scene = load_scene("serve")
    ticks = 300
    result = Supervisor(scene, ticks, "realtime").run()
    assert result.ticks == ticks
    # Paced: the run cannot finish before its simulated time has passed (one tick of slack for
    # the first tick, which is due at the start).
    assert result.wall_seconds >= (ticks - 1) * scene.dt
    late, worst = result.workers["physics"]["late_ticks"], result.workers["physics"]["max_late_s"]
    # a tick counts as late when it started more than one tick after its due time, and the worst
    # lateness is recorded with it: either none was late, or the worst was beyond a tick
    assert 0 <= late <= ticks and ((late == 0 and worst == 0.0) or (late > 0 and worst > scene.dt)), (late, worst)


def test_a_scene_starts_only_the_workers_it_needs():
    assert workers_for(load_scene("drop")) == ["physics"]  # no cloth net, no AI: no such workers


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as stat:
        return int(stat.read().rsplit(")", 1)[1].split()[1])


def _started_by(pid: int, supervisor_pid: int) -> bool:
    """The worker descends from the supervisor (through its forkserver)."""
    for _ in range(3):
        try:
            pid = _parent(pid)
        except (OSError, ValueError, IndexError):  # gone: no file, or ESRCH while it is being reaped
            return False
        if pid == supervisor_pid:
            return True
    return False


def _wait_running(run_ids_before, supervisor_pid, timeout):
    """Handshake through shared memory: the supervisor's physics worker reports RUNNING.

    Other runs (other test workers) may start meanwhile: the run is the one whose worker
    descends from our supervisor.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        new = {name[2:].split("-")[0] for name in leftover_segments()} - run_ids_before
        for run_id in new:
            try:
                status = Arena.attach({"run_id": run_id, "specs": {"status": ("array", STATUS_DTYPE, (1,))}})
            except (FileNotFoundError, ValueError):  # gone, or created and not yet sized ("empty file")
                continue
            try:
                row = status["status"].array[0]
                if row["state"] == WorkerState.RUNNING and _started_by(int(row["pid"]), supervisor_pid):
                    return run_id, int(row["pid"])
            finally:
                status.close()
        time.sleep(0.01)  # polling a shared flag with a deadline, not a sleep used as a handshake
    raise TimeoutError("the run never reported RUNNING")


def test_sigint_to_the_supervisor_leaves_no_process_and_no_segment():
    before = {name[2:].split("-")[0] for name in leftover_segments()}
    cmd = ctrl_c_able("run", "rally", "--processes", "--mode", "realtime", "--ticks", "60000", "--json")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
    try:
        run_id, worker_pid = _wait_running(before, proc.pid, timeout=DEADLINE_S)
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=DEADLINE_S)
        assert proc.returncode != 0
        assert leftover_segments(run_id) == []
        with pytest.raises(ProcessLookupError):
            os.kill(worker_pid, 0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)


def test_cli_processes_check_reference_json():
    done = subprocess.run([sys.executable, "-m", "processes", "run", "serve", "--processes", "--check-reference",
                           "--json"], capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["reference"]["bitwise_equal"] is True
    assert summary["reference"]["ticks_compared"] == load_scene("serve").ticks + 1
    assert summary["workers"]["physics"]["restarts"] == 0
    assert np.isfinite(summary["wall_seconds"])


def test_a_starting_worker_keeps_its_heartbeat_fresh_until_it_is_ready():
    """While a worker compiles its kernels (seconds to minutes, one blocking call) a thread keeps
    its heartbeat fresh, so the supervisor waits on silence, not on a fixed start-up time."""
    import threading

    from processes.runtime import control as worker

    row = np.zeros(1, STATUS_DTYPE)[0]
    row["state"] = WorkerState.STARTING
    started = threading.Event()
    beater = threading.Thread(target=worker._beat_while_starting, args=(row, started), daemon=True)
    beater.start()
    deadline = time.monotonic() + DEADLINE_S
    beats = set()
    while len(beats) < 3 and time.monotonic() < deadline:
        beats.add(float(row["heartbeat"]))
        time.sleep(0.05)  # polling a shared value the thread writes, bounded by the deadline
    assert len(beats - {0.0}) >= 2  # it beat at least twice
    row["state"] = WorkerState.READY  # ready: the thread stops beating and ends
    beater.join(timeout=DEADLINE_S)
    assert not beater.is_alive()


def test_a_worker_that_cannot_be_started_fails_the_run_and_leaves_nothing_behind(no_leftovers, monkeypatch):
    # The error that stopped the start is the one raised (not one of the clean-up's), every worker
    # already started is stopped, and the run's segments are removed.
    import multiprocessing.process

    real_start = multiprocessing.process.BaseProcess.start

    def start(process):
        if process.name == "pingpong-net":
            raise OSError("no process for the net worker (the test's)")
        return real_start(process)

    monkeypatch.setattr(multiprocessing.process.BaseProcess, "start", start)
    with pytest.raises(OSError, match="no process for the net worker"):
        Supervisor(load_scene("net"), 100, "lockstep").run()
