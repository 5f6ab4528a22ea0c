"""DecisionWatchdog: a match played in this process is given up when a bot cannot be interrupted.

The engine interrupts a bot's decision that runs past its hang time (engine.play.players.HangAlarm:
SIGALRM in the main thread). A bot blocked where no signal reaches it (in C code that neither
returns nor takes EINTR, or with SIGALRM blocked) keeps the main thread forever, and with it a
tournament's pool process or a whole `pingpong match --in-process`. This thread looks at the
decision in progress (engine.play.players.decision_in_progress) and, once it is ABANDON_GRACE_S past
its interrupt, hands a description of it to `abandon` and ends the process (os._exit): the
main thread cannot be freed, only left.
"""
from __future__ import annotations

import os
import threading

from engine.play.players import decision_in_progress

ABANDON_GRACE_S = 2.0  # after the interrupt was due: a loaded machine's signal handler has had its chance
LOOK_EVERY_S = 0.1
ABANDONED_EXIT = 3  # the status of a process that gave its match up


class DecisionWatchdog(threading.Thread):
    """Started beside a match played in this process's main thread; stop() when it is over.

    abandon(reason): called on this thread with a sentence naming the bot, before the process
    ends with ABANDONED_EXIT; it must be quick (write a record, print a line).
    """

    def __init__(self, abandon):
        super().__init__(name="decision-watchdog", daemon=True)
        self.abandon = abandon
        self._finished = threading.Event()

    def run(self) -> None:
        while not self._finished.wait(LOOK_EVERY_S):
            current = decision_in_progress()
            if current is None:
                continue
            name, player, seconds, hang_s = current
            if hang_s is not None and seconds > hang_s + ABANDON_GRACE_S:
                reason = (f"bot {name} (player {'AB'[player]}) has not returned from act() for {seconds:.1f} s and "
                          f"could not be interrupted after {hang_s:g} s (blocked where no signal reaches it): "
                          f"the match was abandoned")
                try:
                    self.abandon(reason)
                finally:
                    os._exit(ABANDONED_EXIT)

    def stop(self) -> None:
        self._finished.set()
        if self.is_alive() and self is not threading.current_thread():
            self.join(LOOK_EVERY_S * 10)

    def __enter__(self) -> DecisionWatchdog:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
