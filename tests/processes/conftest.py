"""Process tests: every wait bounded, every process and segment cleaned up even on failure."""
import multiprocessing

import pytest
import zmq

from processes.runtime import shm
from tests.helpers import commands
from tests.helpers.gateway import Rig


@pytest.fixture
def ctx():
    return multiprocessing.get_context("forkserver")


@pytest.fixture
def no_leftovers():
    """Fails the test if a run it started leaves a segment in /dev/shm (other runs on the
    machine, a concurrent CI for one, are not its business)."""
    before = set(shm.created_run_ids)
    yield
    left = [name for run_id in shm.created_run_ids - before for name in shm.leftover_segments(run_id)]
    assert not left, f"segments left behind: {sorted(left)}"


@pytest.fixture
def procs():
    """Processes a test starts; all are killed and joined at the end, whatever happened."""
    started = []
    yield started
    for p in started:
        if p.is_alive():
            p.kill()
        p.join(5)


@pytest.fixture
def zctx():
    """A ZeroMQ context for the test's sockets. A socket the code under test left open is a leak:
    the test fails and names it (after closing it with linger 0, so the context still ends)."""
    context = zmq.Context()
    context.setsockopt(zmq.LINGER, 0)  # a closed socket's unsent messages never hold up the end
    yield context
    leaked = [socket for socket in list(context._sockets) if not socket.closed]
    for socket in leaked:
        socket.close(linger=0)
    context.term()
    assert not leaked, f"sockets left open: {[zmq.SocketType(s.socket_type).name for s in leaked]}"


@pytest.fixture
def rig(zctx):
    """rig(**settings): a Gateway in this process (tests.helpers.gateway.Rig), closed at the end."""
    made = []

    def make(**kwargs):
        made.append(Rig(zctx, **kwargs))
        return made[-1]

    yield make
    for r in made:
        r.close()


@pytest.fixture
def served():
    """The `pingpong` processes a test starts (append them): stopped and reaped at the end,
    whatever happened (tests.helpers.commands.stop)."""
    started = []
    yield started
    commands.stop(started)
