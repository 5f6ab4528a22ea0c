"""A client's session loop: play (bot or keyboard, with prediction) or watch (interpolated) until it ends.

A player predicts with the engine and reconciles on each snapshot (processes.network.client.prediction)
and sends its inputs from the predicted present; a spectator shows the state interpolated 100 ms
behind (processes.network.client.interpolation).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from processes.network import wire
from processes.network.client.client import Client
from processes.network.client.prediction import Predictor, RoundTrip, ServerClock
from processes.network.wire import Kind, Slot

if TYPE_CHECKING:  # for the annotations only: a session imports none of its players' modules
    from processes.network.client.brain import BotBrain
    from processes.network.client.interpolation import Interpolator
    from processes.network.client.keyboard import KeyboardPilot

CONTROL_HZ = 100  # a predicting player's inputs per second (the server's AI arms decide at 100 Hz too)


@dataclass(frozen=True)
class SessionOptions:
    """Who plays a session and how it is shown (run_session); the defaults watch, showing nothing.

    Attributes:
        brain: a BotBrain (with a predictor: inputs at CONTROL_HZ from the predicted state;
            without: from each newest snapshot).
        pilot, keys: a keyboard.KeyboardPilot and a key source (inputs at CONTROL_HZ from the
            predicted bat). predictor: a prediction.Predictor (a player): reconciled on each
            snapshot, advanced to the server's estimated present, stamps our inputs.
        view: an interpolation.Interpolator (a spectator).
        seconds: s, the session ends after this long at most.
        show(summary, frame): called at most every show_every_s (s) with the summary so far and
            the frame to draw (the interpolated state of a spectator, the predicted state of a
            player, else the last snapshot).
        clock: the session's clock, s (time.monotonic).
    """

    brain: BotBrain | None = None
    pilot: KeyboardPilot | None = None
    keys: Any = None
    predictor: Predictor | None = None
    view: Interpolator | None = None
    seconds: float = 3600.0
    show: Callable[[dict, dict], None] | None = None
    show_every_s: float = 0.25
    clock: Callable[[], float] = time.monotonic


def run_session(client: Client, welcome: wire.Message, options: SessionOptions = SessionOptions()) -> dict:
    """Play or watch until the server says goodbye, falls silent, the keys say quit or
    options.seconds pass. client: joined (welcome taken).

    Returns:
        The summary: snapshots, events, inputs_sent, goodbye, the last snapshot's tick and score,
        prediction statistics (a player with a predictor) or interpolation counts (a spectator).
    """
    brain, pilot, keys, predictor, view = options.brain, options.pilot, options.keys, options.predictor, options.view
    show, show_every_s, clock = options.show, options.show_every_s, options.clock
    seconds = options.seconds
    dt = welcome["dt"]
    server_clock = ServerClock(dt)
    round_trip = RoundTrip()
    summary = {"snapshots": 0, "events": [], "inputs_sent": 0}
    deadline = clock() + seconds
    next_control = next_show = 0.0
    wait_ms = 2 if pilot is not None else (10 if predictor is not None else 50)
    last = None
    quit_pressed = False

    def present() -> int:
        """The tick an input sent now takes effect at on the server: its estimated present
        (which lags by the one-way trip) plus the round trip."""
        estimate = server_clock.tick_at(clock())
        if estimate is None:
            return client.tick
        return max(int(estimate + round_trip.seconds / dt), last.tick)

    def send(inputs) -> None:
        tick = present()
        client.send_input(inputs, tick=tick)
        round_trip.sent(client.seq, clock())
        summary["inputs_sent"] += 1
        if predictor is not None:
            predictor.record_input(client.seq, tick, inputs)

    while clock() < deadline and client.goodbye is None and not client.server_lost and not quit_pressed:
        client.heartbeat_if_due()
        newest = None
        for message in client.recv_batch(wait_ms):  # all that waits: only the newest state is acted on
            now = clock()
            if message.kind == Kind.SNAPSHOT:
                summary["snapshots"] += 1
                server_clock.observe(message.tick, now)
                if view is not None:
                    view.push(message, now)
                if newest is None or message.tick > newest.tick:
                    newest = message
            elif message.kind == Kind.EVENT:
                event = message.to_dict()
                keep = ("event", "winner", "reason_name", "score", "games_won")
                summary["events"].append({k: event[k] for k in keep})
        now = clock()
        if newest is not None:
            summary["snapshots_acted_on"] = summary.get("snapshots_acted_on", 0) + 1
            last = newest
            if client.slot != Slot.NONE:
                round_trip.acked(int(newest["input_seq"][client.slot.bat]), now)
            if predictor is not None:
                predictor.reconcile(newest)
            if brain is not None and predictor is None:
                send(brain.control(newest, dt))  # no prediction: decide from each newest snapshot
        if predictor is not None and last is not None:
            predictor.advance_to(present())
        if keys is not None:
            for key in keys.poll():
                if key == "quit":
                    quit_pressed = True
                elif pilot is not None:
                    pilot.press(key, now)
        if predictor is not None and last is not None and now >= next_control and (pilot or brain) is not None:
            next_control = max(next_control + 1.0 / CONTROL_HZ, now)  # from the predicted present
            if predictor.stale:
                summary["stale_controls_skipped"] = summary.get("stale_controls_skipped", 0) + 1
            else:
                send(pilot.control(now, predictor.bat) if pilot is not None else brain.control(last, dt, predictor))
        if now >= next_show and last is not None:
            next_show = now + show_every_s
            frame = _frame(last, predictor, view, pilot, now)  # sampled also unseen: the counts report it
            if show is not None:
                show(summary, frame)
    if client.goodbye is None:
        client.leave()
    summary["goodbye"] = client.goodbye.name.lower() if client.goodbye else (
        "server_lost" if client.server_lost else "quit" if quit_pressed else "left")
    if last is not None:
        summary.update(tick=last.tick, score=last["score"].tolist(), games_won=last["games_won"].tolist(),
                       winner=int(last["winner"]), input_seq=last["input_seq"].tolist())
    if predictor is not None:
        summary["prediction"] = predictor.stats()
    if summary["inputs_sent"]:
        summary["round_trip"] = round_trip.summary()
    if view is not None:
        summary["interpolation"] = {"delay_ms": view.delay_s * 1000.0, **view.counts}
    summary["dropped"] = dict(client.drops.by_reason)
    if client.feed_address:
        summary["feed_missed"] = client.feed_missed  # snapshots and events the gateway dropped at the mark
    return summary


def _frame(last: wire.Message, predictor, view, pilot, now: float) -> dict:
    """What to draw now: positions, the tick they are at, the snapshot with the score."""
    frame = {"snapshot": last, "tick": float(last.tick), "ball_pos": last["ball_pos"], "ball_vel": last["ball_vel"],
             "bat_pos": np.array(last["bat_pos"]), "target": None}
    if view is not None:
        shown = view.sample(now)
        if shown is not None:
            frame.update(tick=shown["tick"], ball_pos=shown["ball_pos"], ball_vel=shown["ball_vel"],
                         bat_pos=shown["bat_pos"], snapshot=shown["snapshot"])
    if predictor is not None and predictor.tick is not None:
        frame["bat_pos"][predictor.player] = predictor.bat["pos"]
        frame.update(tick=float(predictor.tick), ball_pos=np.array(predictor.ball["pos"]),
                     ball_vel=np.array(predictor.ball["vel"]))
    if pilot is not None:
        frame["target"] = pilot.aim(now)
    return frame
