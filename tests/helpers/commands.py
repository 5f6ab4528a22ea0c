"""`pingpong` as a child process the way a terminal runs it, and the process tree it leaves (or not)."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[2]


def ctrl_c_able(*args: str) -> list[str]:
    """The command line of `pingpong ARGS` as a terminal's foreground job runs it: with SIGINT's
    default handling. A process started with SIGINT ignored keeps ignoring it and Python then
    installs no KeyboardInterrupt handler (POSIX: a non-interactive shell starts its background
    jobs that way, so under `nohup make test &` every child ignored Ctrl-C and the Ctrl-C tests
    failed); a test of what Ctrl-C does must not inherit that."""
    return [sys.executable, "-c", "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
            "from processes import main; sys.exit(main(sys.argv[1:]))", *args]


def pingpong(*args) -> subprocess.Popen:
    """`pingpong ARGS` in a session of its own, with SIGINT's default handling (ctrl_c_able)."""
    return subprocess.Popen(ctrl_c_able(*args), cwd=ROOT, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def descendants(pid: int) -> set[int]:
    """Every process below `pid` (children, theirs, ...), from /proc."""
    found, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = (task / "children").read_text().split()
            except OSError:
                continue
            for child in map(int, children):
                if child not in found:
                    found.add(child)
                    todo.append(child)
    return found


def alive(pid: int) -> bool:
    """`pid` runs (it exists and is no zombie)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().split("State:")[1].split("\n")[0]
    except (OSError, IndexError):
        return False


def await_gone(pids, seconds=DEADLINE_S):
    """The processes of `pids` still alive after waiting up to `seconds` for them all to end."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)  # polling for exits of other processes, bounded
    return [p for p in pids if alive(p)]


def stop(started) -> None:
    """Stop and reap the `pingpong` processes `started`, whatever happened.

    SIGTERM first, so a server's supervisor removes its shared memory (a SIGKILLed supervisor
    cannot: a test that failed mid-match left its segments in /dev/shm); then SIGKILL to the
    whole session for whatever is left."""
    for proc in started:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                pass
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
        proc.stdout.close()
        proc.stderr.close()
