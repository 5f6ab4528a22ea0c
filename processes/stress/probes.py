"""What /proc says about a process: CPU seconds (whole and per thread), descriptors, resident memory;
and the machine's load average and shared-memory segments."""
from __future__ import annotations

import os
import time
from pathlib import Path

CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int | str = "self") -> float | None:
    """User + system CPU seconds of a process (/proc/PID/stat fields 14, 15); None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def fd_count(pid: int | str = "self") -> int | None:
    """Open descriptors of a process; None once it is gone."""
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None


def rss_kb(pid: int | str = "self") -> int | None:
    """Resident set size of a process in KiB (/proc/PID/status VmRSS); None once it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def shm_names() -> set[str]:
    return set(os.listdir("/dev/shm")) if os.path.isdir("/dev/shm") else set()


def loadavg() -> list[float]:
    """The 1, 5 and 15 minute load averages: how far to trust times taken on a shared machine."""
    return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]


def _thread_ids(pid: int | str) -> list[str]:
    """The thread ids of a process (/proc/PID/task), [] once it is gone."""
    try:
        return os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []


def thread_cpu_seconds(pid: int | str = "self") -> dict[str, float]:
    """CPU seconds of each thread of a process, summed by thread name (/proc/PID/task/TID/stat:
    the Python thread is named like its program, libzmq's are ZMQbg/IO/0, ZMQbg/Reaper)."""
    out: dict[str, float] = {}
    for tid in _thread_ids(pid):
        try:
            text = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
        except OSError:
            continue
        name = text[text.index("(") + 1:text.rindex(")")]
        fields = text.rsplit(")", 1)[1].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / CLK_TCK
    return out


def thread_sched_seconds(pid: int | str = "self") -> dict[str, tuple[float, float]]:
    """Per thread name (summed as in thread_cpu_seconds): (seconds on a CPU, seconds runnable but
    waiting for one), from /proc/PID/task/TID/schedstat (nanoseconds; sched-stats.rst of the Linux
    documentation); {} without schedstats. Their sum over a wall time says how much a thread wanted
    to run: near all of it, it always had work left, whatever share of a CPU it was given."""
    out: dict[str, tuple[float, float]] = {}
    for tid in _thread_ids(pid):
        try:
            name = Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip()
            on_cpu, waiting = Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()[:2]
        except (OSError, ValueError):
            continue
        before = out.get(name, (0.0, 0.0))
        out[name] = (before[0] + int(on_cpu) / 1e9, before[1] + int(waiting) / 1e9)
    return out


class CpuMeter:
    """CPU time of named processes between start() and stop(), as % of one core; for the
    processes named in `threads`, also per thread name (e.g. the gateway's libzmq I/O thread)."""

    def __init__(self, threads=()):
        self.t0 = 0.0
        self.threads = set(threads)
        self.start_cpu: dict[str, tuple[int, float]] = {}
        self.start_threads: dict[str, tuple[int, dict]] = {}
        self.result: dict[str, float] = {}

    def start(self, pids: dict[str, int]) -> None:
        self.t0 = time.monotonic()
        self.start_cpu = {name: (pid, cpu_seconds(pid)) for name, pid in pids.items() if cpu_seconds(pid) is not None}
        self.start_threads = {name: (pid, thread_cpu_seconds(pid)) for name, pid in pids.items() if name in self.threads}

    def stop(self) -> dict[str, float | None]:
        """% of one core per process; None for one that exited meanwhile (a match that ended
        early takes its server's processes with it: their CPU time is gone with them)."""
        wall = max(time.monotonic() - self.t0, 1e-9)
        for name, (pid, c0) in self.start_cpu.items():
            c1 = cpu_seconds(pid)
            self.result[name] = None if c1 is None else round(100.0 * (c1 - c0) / wall, 1)
        for name, (pid, before) in self.start_threads.items():
            for thread, c1 in thread_cpu_seconds(pid).items():
                self.result[f"{name}[{thread}]"] = round(100.0 * (c1 - before.get(thread, 0.0)) / wall, 1)
        self.result["_wall_s"] = round(wall, 2)
        return self.result
