"""StopSignals: a stop signal held while the run is built, raised once, ignored while it stops.

The signals are sent to this process (os.kill is delivered before it returns when the target is
the calling process: POSIX); the handlers are restored after each test.
"""
import os
import signal

import pytest

from processes.runtime.stops import StopSignals


@pytest.fixture
def stops():
    before = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)}
    stops = StopSignals().install()
    yield stops
    stops.restore()
    for signum, handler in before.items():  # a raised stop leaves them ignored (restore's docstring)
        signal.signal(signum, handler)


def test_a_signal_while_building_is_held_and_raised_once_armed(stops):
    os.kill(os.getpid(), signal.SIGTERM)
    os.kill(os.getpid(), signal.SIGINT)  # one request: the first one is the one raised
    assert stops.held == signal.SIGTERM
    with pytest.raises(SystemExit) as stopped:
        stops.arm()
    assert stopped.value.code == 143


def test_an_armed_signal_raises_and_the_next_ones_are_ignored(stops):
    stops.arm()
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
    for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGTERM):
        os.kill(os.getpid(), signum)  # the stop is under way: nothing raised
    assert stops.ignored == 3


def test_shielded_signals_are_counted_and_the_old_handlers_come_back():
    before = signal.getsignal(signal.SIGTERM)
    stops = StopSignals().install()
    stops.arm()
    stops.shield()
    os.kill(os.getpid(), signal.SIGTERM)
    assert stops.ignored == 1
    stops.restore()
    assert signal.getsignal(signal.SIGTERM) is before


def test_an_ignored_sigint_stays_ignored():
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell starts a background job
    try:
        stops = StopSignals().install()
        stops.arm()
        os.kill(os.getpid(), signal.SIGINT)
        assert stops.ignored == 0 and stops.held is None
        stops.restore()
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


def test_after_a_raised_stop_the_signals_stay_ignored_for_the_owners_last_words():
    before = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)}
    stops = StopSignals().install()
    try:
        stops.arm()
        with pytest.raises(SystemExit):
            os.kill(os.getpid(), signal.SIGTERM)
        stops.shield()
        stops.restore()
        for signum in (signal.SIGTERM, signal.SIGINT):
            assert signal.getsignal(signum) == signal.SIG_IGN
        os.kill(os.getpid(), signal.SIGTERM)  # ignored: this process goes on to say what it must
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
