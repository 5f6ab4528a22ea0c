"""The network client: a session with the gateway (DEALER socket), the bot brain, `pingpong join`.

A client says hello, waits (bounded) for welcome or reject, then exchanges wire messages: it
sends a heartbeat at least as often as the welcome asks, inputs for its own bat, and goodbye
when it leaves; it takes snapshots, events, heartbeats and the server's goodbye. Every wait is
bounded and a server silent past the welcome's timeout ends the session. A spectator whose
welcome names a feed (welcome.feed_port) subscribes to it (a SUB socket, CURVE like the
session) and takes its snapshots and events there; the session still carries heartbeats and
goodbye, and only the session says whether the server is alive. Gaps in the feed's sequence
numbers are the messages the gateway dropped at the high-water mark (`feed_missed`).

`run_session` is the loop of `pingpong join`: a player (bot or keyboard) predicts with the
engine and reconciles on each snapshot (processes/prediction.py) and sends its inputs from the
predicted present; a spectator shows the state interpolated 100 ms behind. CURVE keys
(`pingpong keys DIR`) make the session encrypted and the server authenticated.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import zmq

from processes.network import wire
from processes.network.wire import GoodbyeReason, InputMode, Kind, Role, Slot

NO_TOKEN = bytes(wire.TOKEN_SIZE)
JOIN_TIMEOUT_S = 10.0


def load_curve_key(path: str, secret: bool) -> tuple[bytes, bytes | None]:
    """(public, secret) Z85 keys from a ZeroMQ certificate file (zmq.auth.create_certificates,
    `pingpong keys DIR`); secret=True needs the secret file (NAME.key_secret)."""
    import zmq.auth

    try:
        public, secret_key = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: not a ZeroMQ certificate ({err}); make one with `pingpong keys DIR`") from None
    if public is None or len(public) != 40:
        raise ValueError(f"{path}: no 40-character Z85 public key in it; make one with `pingpong keys DIR`")
    if secret and (secret_key is None or len(secret_key) != 40):
        raise ValueError(f"{path}: no secret key in it; the server needs the .key_secret file of `pingpong keys DIR`")
    return public, secret_key


def curve_client_options(server_key_file: str | None) -> dict:
    """Socket options of a CURVE client of the server whose public key is in that file (a fresh
    key pair of our own each session; the server authenticates itself, the session is
    encrypted); {} without a file."""
    if not server_key_file:
        return {}
    if not zmq.has("curve"):
        raise ValueError("this libzmq has no CURVE support; install pyzmq's wheel (it bundles libsodium)")
    server_public, _ = load_curve_key(server_key_file, secret=False)
    public, secret = zmq.curve_keypair()
    return {zmq.CURVE_SERVERKEY: server_public, zmq.CURVE_PUBLICKEY: public, zmq.CURVE_SECRETKEY: secret}


def keys_command(args: argparse.Namespace) -> int:
    """`pingpong keys DIR`: a server key pair for CURVE (server.key to give clients,
    server.key_secret to keep)."""
    import os

    import zmq.auth

    os.makedirs(args.dir, exist_ok=True)
    public_file, secret_file = zmq.auth.create_certificates(args.dir, args.name)
    os.chmod(secret_file, 0o600)
    if args.json:
        print(json.dumps({"public": public_file, "secret": secret_file}))
    else:
        print(f"public key (give it to clients): {public_file}\nsecret key (keep it): {secret_file}\n"
              f"pingpong serve --curve-secret {secret_file}   pingpong join ADDRESS --curve-server-key {public_file}")
    return 0


def feed_address(session_address: str, port: int) -> str:
    """The feed's endpoint: the session's tcp:// host with the welcome's feed_port."""
    if not session_address.startswith("tcp://") or not 0 < port < 65536:
        raise ValueError(f"a feed on port {port} needs a tcp:// session address, got {session_address!r}")
    return f"{session_address.rsplit(':', 1)[0]}:{port}"


class Rejected(RuntimeError):
    """The server turned the hello away; `reason` is a wire.RejectReason."""

    def __init__(self, reason, detail: str):
        super().__init__(f"rejected: {reason.name.lower()}: {detail}")
        self.reason = reason
        self.detail = detail


class Client:
    """One session with a gateway.

    Args:
        address: the server's ZeroMQ endpoint. role: "player" or "spectator". name: shown to others.
        slot: the seat wanted (Slot.NONE: any). token: a rejoin token from an earlier welcome.
        zctx: a zmq.Context (a new one by default, terminated on close).
        socket_options: extra {zmq option: value} set before connecting (the session's socket
            and the feed's: CURVE keys, buffers). feed_options: more for the feed's socket only
            (e.g. zmq.AFFINITY: a process of many clients reads its feeds on an I/O thread of
            their own, so its heartbeats do not queue behind them).
    """

    def __init__(self, address: str, role: str = "spectator", name: str = "client", slot: Slot = Slot.NONE,
                 token: bytes = NO_TOKEN, zctx=None, socket_options: dict | None = None,
                 feed_options: dict | None = None):
        self.address = address
        self.role = Role.PLAYER if role == "player" else Role.SPECTATOR
        self.name = name
        self.wanted = slot
        self.token = token
        self._own_ctx = zctx is None
        self.zctx = zctx or zmq.Context()
        self.socket_options = dict(socket_options or {})
        self.feed_options = dict(feed_options or {})
        self.sock = self.zctx.socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.setsockopt(zmq.RCVHWM, 256)
        for option, value in self.socket_options.items():
            self.sock.setsockopt(option, value)
        self.sock.connect(address)
        self.feed = None  # the SUB socket of a spectator's feed, once a welcome names one
        self.feed_address = ""
        self.feed_seq = 0  # last seq seen on the feed
        self.feed_missed = 0  # gaps in the feed's seqs: messages dropped at the gateway's high-water mark
        self._poller = zmq.Poller()
        self._poller.register(self.sock, zmq.POLLIN)
        self.seq = 0
        self.tick = 0
        self.slot = Slot.NONE
        self.welcome: wire.Message | None = None
        self.drops = wire.DropCounter()
        self.received = 0
        self.goodbye: GoodbyeReason | None = None
        self.last_seen = time.monotonic()
        self._next_beat = 0.0
        self.heartbeat_s = 0.5
        self.timeout_s = 5.0
        self.max_seq_in = 0

    def send(self, kind, **fields) -> None:
        self.seq += 1
        self.sock.send(wire.encode(kind, seq=self.seq, tick=self.tick, **fields), flags=zmq.NOBLOCK)

    def send_raw(self, data: bytes) -> None:
        """Bytes as they are (tests of the gateway's validation)."""
        self.sock.send(data, flags=zmq.NOBLOCK)

    def hello(self) -> None:
        """Ask for a seat (or to watch); the answer comes as a welcome or a reject (see accept)."""
        token = self.token if self.role == Role.PLAYER else NO_TOKEN
        self.send(Kind.HELLO, role=self.role, slot=self.wanted if self.role == Role.PLAYER else Slot.NONE,
                  name=self.name, token=token)

    def accept(self, message: wire.Message) -> bool:
        """Take the server's answer to the hello: True on a welcome, Rejected on a reject,
        False for anything else."""
        if message.kind == Kind.REJECT:
            raise Rejected(message["reason"], message["detail"])
        if message.kind != Kind.WELCOME:
            return False
        self.welcome = message
        self.slot = message["slot"]
        self.token = message["token"]
        self.heartbeat_s = message["heartbeat_ms"] / 1000.0
        self.timeout_s = message["timeout_ms"] / 1000.0
        self._next_beat = time.monotonic() + self.heartbeat_s
        self.subscribe(message["feed_port"])
        return True

    def subscribe(self, port: int) -> None:
        """Take snapshots and events from the feed on `port` of the session's host (0: none,
        they come on the session). A welcome of a restarted gateway may name another port: the
        old feed is closed and the new one subscribed."""
        address = feed_address(self.address, port) if port else ""
        if address == self.feed_address:
            return
        if self.feed is not None:
            self._poller.unregister(self.feed)
            self.feed.close(linger=0)
            self.feed = None
        self.feed_address, self.feed_seq = address, 0
        if not address:
            return
        feed = self.zctx.socket(zmq.SUB)
        feed.setsockopt(zmq.LINGER, 0)
        feed.setsockopt(zmq.RCVHWM, 256)
        for option, value in {**self.socket_options, **self.feed_options}.items():
            feed.setsockopt(option, value)
        feed.setsockopt(zmq.SUBSCRIBE, b"")
        feed.connect(address)
        self.feed = feed
        self._poller.register(feed, zmq.POLLIN)

    def _waiting(self, timeout_ms: int):
        """The sockets with a message waiting (the session first), after at most timeout_ms."""
        if self.feed is None:
            return [self.sock] if self.sock.poll(timeout_ms, zmq.POLLIN) else []
        ready = dict(self._poller.poll(timeout_ms))
        return [sock for sock in (self.sock, self.feed) if sock in ready]

    def join(self, timeout_s: float = JOIN_TIMEOUT_S) -> wire.Message:
        """Say hello and wait (bounded) for the welcome; raises Rejected or TimeoutError."""
        self.hello()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            message = self.recv(int(1000 * min(0.2, max(deadline - time.monotonic(), 0.0))) + 1)
            if message is not None and self.accept(message):
                return message
        raise TimeoutError(f"no welcome from {self.address} within {timeout_s} s")

    def recv(self, timeout_ms: int) -> wire.Message | None:
        """The next valid message within timeout_ms, session or feed, or None (bad ones are
        counted and dropped)."""
        waiting = self._waiting(timeout_ms)
        if not waiting:
            return None
        sock = waiting[0]
        try:
            data = sock.recv(flags=zmq.NOBLOCK)
        except zmq.Again:
            return None
        message = self.drops.decode(data)
        if message is None:
            return None
        self.received += 1
        self.tick = max(self.tick, message.tick)
        if sock is self.feed:
            if message.kind not in (Kind.SNAPSHOT, Kind.EVENT):
                self.drops.by_reason["not_on_feed"] += 1  # only snapshots and events go out on the feed
                return None
            if self.feed_seq and message.seq > self.feed_seq:
                self.feed_missed += message.seq - self.feed_seq - 1
            self.feed_seq = message.seq
            return message
        self.last_seen = time.monotonic()  # only the session says the server is alive
        self.max_seq_in = max(self.max_seq_in, message.seq)
        if message.kind == Kind.GOODBYE:
            self.goodbye = message["reason"]
        return message

    def recv_batch(self, timeout_ms: int, limit: int = 256) -> list[wire.Message]:
        """Every valid message waiting (at most `limit`), waiting at most timeout_ms for the
        first: a loop that handles them all at once never falls behind the server."""
        messages = []
        if not self._waiting(timeout_ms):
            return messages
        for _ in range(limit):
            message = self.recv(0)
            if message is not None:
                messages.append(message)
            elif not self._waiting(0):
                break
        return messages

    def heartbeat_if_due(self) -> None:
        now = time.monotonic()
        if now >= self._next_beat:
            self._next_beat = now + self.heartbeat_s
            self.send(Kind.HEARTBEAT, ack=self.max_seq_in)

    @property
    def server_lost(self) -> bool:
        return time.monotonic() - self.last_seen > self.timeout_s

    def send_input(self, inputs, tick: int | None = None, slot: Slot | None = None) -> None:
        """Force (N) and torque (N m), world frame, for our bat (slot: tests may name another)."""
        inputs = np.asarray(inputs, dtype=np.float64)
        if tick is not None:
            self.tick = tick
        self.send(Kind.INPUT, slot=self.slot if slot is None else slot, mode=InputMode.FORCE, force=inputs[0:3],
                  torque=inputs[3:6], target_pos=np.zeros(3), target_quat=np.zeros(4))

    def leave(self) -> None:
        try:
            self.send(Kind.GOODBYE, reason=GoodbyeReason.QUIT)
        except zmq.ZMQError:
            pass

    def close(self) -> None:
        if self.feed is not None:
            self.feed.close(linger=0)
        self.sock.close(linger=0)
        if self._own_ctx:
            self.zctx.term()


class BotBrain:
    """engine.ai.BatAI playing one bat from the server's snapshots (`pingpong join --bot`).

    The AI sees what the snapshot carries. The rally key of the in-process match is (rally,
    shots); the snapshot carries no shot count, so the bot counts the strikes it sees (the
    striker changes, or the phase leaves waiting-for-serve), which changes at the same moments.
    """

    def __init__(self, scene_name: str, slot: Slot, skill: str = "pro", seed: int = 0):
        from engine.ai import SKILLS, BatAI
        from engine.dtypes import BAT_DTYPE
        from engine.scene import load_scene
        from engine.world import build_model

        self.scene = load_scene(scene_name)
        self.model = build_model(self.scene)
        self.player = int(slot) - 1
        self.ai = BatAI(self.model, self.player, SKILLS[skill], seed=seed * 1000 + self.player)
        self.ai.warm_up()
        self.bat = np.zeros((), BAT_DTYPE)
        self.ball_y = np.zeros(9)
        self.out = np.zeros(6)
        self._last = None
        self._turns = 0

    def control(self, snapshot: wire.Message, dt: float, predictor=None) -> np.ndarray:
        """(6,) force and torque for our bat after this snapshot.

        predictor: a prediction.Predictor reconciled with the snapshot: the AI then decides from
        the predicted ball and bat at the predicted tick (the server's present, as far as the
        client knows), not from the snapshot's past: the arm's PD loop would otherwise act on
        states a round trip old, and a loop with kd = 60/s goes unstable beyond ~25 ms of delay.
        The snapshot still says whose turn it is (phase, server, striker, rally).
        """
        from engine.rules import Phase, next_striker

        p = self.player
        if predictor is not None and predictor.tick is not None:
            ball, bat, now = predictor.ball, predictor.bat, predictor.tick * dt
            self.ball_y[0:3], self.ball_y[3:6], self.ball_y[6:9] = ball["pos"], ball["vel"], ball["spin"]
            self.bat["pos"], self.bat["quat"], self.bat["vel"], self.bat["ang_vel"] = (
                bat["pos"], bat["quat"], bat["vel"], bat["ang_vel"])
        else:
            now = snapshot.tick * dt
            self.ball_y[0:3], self.ball_y[3:6], self.ball_y[6:9] = (snapshot["ball_pos"], snapshot["ball_vel"],
                                                                    snapshot["ball_spin"])
            self.bat["pos"], self.bat["quat"] = snapshot["bat_pos"][p], snapshot["bat_quat"][p]
            self.bat["vel"], self.bat["ang_vel"] = snapshot["bat_vel"][p], snapshot["bat_ang_vel"][p]
        phase, server, striker, rally = int(snapshot["phase"]), snapshot["server"], snapshot["striker"], snapshot["rally"]
        last = self._last
        if last is None or rally != last[0]:
            self._turns = 0
        elif striker != last[2] or (last[1] == Phase.WAITING_SERVE and phase != Phase.WAITING_SERVE):
            self._turns += 1  # a strike: a return (the striker changed) or the service
        self._last = (rally, phase, striker)
        my_turn = next_striker(phase, int(server), int(striker)) == p
        return self.ai.control(now, self.ball_y, self.bat, (rally, self._turns), my_turn,
                               phase == Phase.WAITING_SERVE, -1 if p == 0 else 1, self.out)


def _score_line(snapshot: wire.Message, ball_pos=None, ball_vel=None, tick=None) -> str:
    s, g = snapshot["score"], snapshot["games_won"]
    b = snapshot["ball_pos"] if ball_pos is None else ball_pos
    v = snapshot["ball_vel"] if ball_vel is None else ball_vel
    tick = snapshot.tick if tick is None else tick
    return (f"tick {tick:>9.1f}  games {g[0]}-{g[1]}  points {s[0]}-{s[1]}  rally {snapshot['rally']}  "
            f"ball ({b[0]:+.2f}, {b[1]:+.2f}, {b[2]:+.2f}) m  |v| {float(np.linalg.norm(v)):.1f} m/s")


def _error_line(name: str, stats: dict) -> str:
    if not stats["n"]:
        return f"{name}: no samples"
    return (f"{name}: mean {stats['mean_mm']:.2f}  p50 {stats['p50_mm']:.2f}  p99 {stats['p99_mm']:.2f}  "
            f"max {stats['max_mm']:.2f} mm  ({stats['n']} snapshots)")


CONTROL_HZ = 100  # a predicting player's inputs per second (the server's AI arms decide at 100 Hz too)


def run_session(client: Client, welcome: wire.Message, *, brain=None, pilot=None, keys=None, predictor=None,
                view=None, seconds: float = 3600.0, show=None, show_every_s: float = 0.25,
                clock=time.monotonic) -> dict:
    """Play or watch until the server says goodbye, falls silent, the keys say quit or `seconds` pass.

    Args:
        client: joined (welcome taken). brain: a BotBrain (with a predictor: inputs at CONTROL_HZ
            from the predicted state; without: from each newest snapshot).
        pilot, keys: a keyboard.KeyboardPilot and a key source (inputs at CONTROL_HZ from the
            predicted bat). predictor: a prediction.Predictor (a player): reconciled on each
            snapshot, advanced to the server's estimated present, stamps our inputs.
        view: a prediction.Interpolator (a spectator). show(summary, frame): called at most every
            show_every_s with the summary so far and the frame to draw (the interpolated state
            of a spectator, the predicted state of a player, else the last snapshot).

    Returns:
        The summary: snapshots, events, inputs_sent, goodbye, the last snapshot's tick and score,
        prediction statistics (a player with a predictor) or interpolation counts (a spectator).
    """
    from processes.network.prediction import RoundTrip, ServerClock

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
                summary["events"].append({k: event[k] for k in ("event", "winner", "score", "games_won")})
        now = clock()
        if newest is not None:
            summary["snapshots_acted_on"] = summary.get("snapshots_acted_on", 0) + 1
            last = newest
            if client.slot != Slot.NONE:
                round_trip.acked(int(newest["input_seq"][int(client.slot) - 1]), now)
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


def keyboard_screen(summary: dict, frame: dict, slot: Slot, predictor=None) -> str:
    """The keyboard player's screen: score, top view, keys, prediction error so far."""
    from processes.network.keyboard import top_view

    lines = [f"pingpong - you play {slot.name} (+ is your target)",
             _score_line(frame["snapshot"], frame["ball_pos"], frame["ball_vel"], frame["tick"]), ""]
    lines += top_view(frame["ball_pos"], frame["bat_pos"], frame["target"])
    lines += ["", "w/s or up/down: forward/back   a/d or left/right: sideways   r/f: up/down   space: stroke   "
                  "q: leave"]
    if predictor is not None:
        stats = predictor.stats()
        lines += [_error_line("prediction error, ball", stats["ball"]), _error_line("prediction error, bat ", stats["bat"])]
    lines.append(f"inputs sent {summary['inputs_sent']}  snapshots {summary['snapshots']}")
    return "\n".join(lines)


def join_command(args: argparse.Namespace) -> int:
    """`pingpong join ADDRESS --as player|spectator [--bot]`."""
    keyboard = args.role == "player" and not args.bot
    if keyboard and not sys.stdin.isatty():
        print("pingpong join: keyboard play needs a terminal (stdin is not a TTY); join a player with --bot, "
              "or --as spectator", file=sys.stderr)
        return 2
    slot = {"any": Slot.NONE, "a": Slot.A, "b": Slot.B}[args.slot]
    try:
        token = bytes.fromhex(args.token) if args.token else NO_TOKEN
        socket_options = curve_client_options(getattr(args, "curve_server_key", None))
    except (ValueError, OSError) as err:
        print(f"pingpong join: {err}", file=sys.stderr)
        return 2
    if args.role == "player":
        if not args.json:
            print("loading the engine's kernels (compiled on a first run) ...", file=sys.stderr, flush=True)
        _warm_up(args.skill)  # before the hello: a cold numba cache compiles for minutes, no heartbeats meanwhile
    client = Client(args.address, args.role, args.name, slot, token, socket_options=socket_options)
    summary = {"address": args.address, "role": args.role, "snapshots": 0, "events": [], "inputs_sent": 0}
    try:
        try:
            welcome = client.join(args.join_timeout)
        except Rejected as err:
            summary.update(rejected=err.reason.name.lower(), detail=err.detail)
            print(json.dumps(summary) if args.json else f"pingpong join: {err}", file=sys.stdout if args.json else sys.stderr)
            return 3
        except TimeoutError as err:
            print(f"pingpong join: {err}", file=sys.stderr)
            return 4
        summary.update(slot=client.slot.name.lower(), scene=welcome["scene"], token=client.token.hex(),
                       snapshot_hz=welcome["snapshot_hz"])
        if not args.json and not keyboard:
            print(f"joined {welcome['scene']} as {'player ' + client.slot.name if client.slot else 'spectator'}"
                  f" (best of {welcome['best_of']}, {welcome['snapshot_hz']} snapshots/s)", flush=True)
        summary.update(_play(client, welcome, args, keyboard))
    except KeyboardInterrupt:
        client.leave()
        summary["goodbye"] = "interrupted"
    finally:
        client.close()
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"session ended: {summary['goodbye']}; {summary['snapshots']} snapshots, "
              f"{len(summary['events'])} events")
        if "prediction" in summary:
            prediction, stale = summary["prediction"], summary["prediction"]["without_prediction"]
            print(_error_line("prediction error at the snapshots' ticks, ball", prediction["ball"]))
            print(_error_line("prediction error at the snapshots' ticks, own bat", prediction["bat"]))
            print(_error_line("without prediction (the previous snapshot), ball", stale["ball"]))
            print(_error_line("without prediction (the previous snapshot), own bat", stale["bat"]))
    return 1 if summary["goodbye"] == "server_lost" else 0


def _warm_up(skill: str) -> None:
    """Load (or compile) every kernel a player's client runs, with the bundled match scene: the
    kernels depend on types, not on the scene, so the served scene's objects build at once later."""
    from engine.scene import load_scene
    from processes.network.prediction import Predictor

    Predictor(load_scene("match"), Slot.A).advance_to(0)
    BotBrain("match", Slot.A, skill)


def _play(client: Client, welcome: wire.Message, args: argparse.Namespace, keyboard: bool) -> dict:
    """The session of `pingpong join` once welcomed: bot, keyboard or spectator."""
    from processes.network.prediction import Interpolator, Predictor

    if client.slot == Slot.NONE:
        view = Interpolator(welcome["dt"], args.delay_ms / 1000.0)

        def show(summary, frame):
            print(_score_line(frame["snapshot"], frame["ball_pos"], frame["ball_vel"], frame["tick"]), flush=True)

        return run_session(client, welcome, view=view, seconds=args.seconds, show=None if args.json else show)
    from engine.scene import load_scene

    scene = load_scene(welcome["scene"])
    predictor = Predictor(scene, client.slot)
    if not keyboard:
        brain = BotBrain(welcome["scene"], client.slot, args.skill, args.seed)
        return run_session(client, welcome, brain=brain, predictor=predictor, seconds=args.seconds)
    from rich.console import Console
    from rich.live import Live
    from rich.text import Text

    from processes.network.keyboard import KeyboardPilot, TerminalKeys

    pilot = KeyboardPilot(predictor.model, client.slot, args.skill)
    with TerminalKeys(sys.stdin.fileno()) as keys, Live(Text("joining ..."), console=Console(),
                                                        auto_refresh=False, transient=False) as live:
        def show(summary, frame):
            live.update(Text(keyboard_screen(summary, frame, client.slot, predictor)), refresh=True)

        return run_session(client, welcome, pilot=pilot, keys=keys, predictor=predictor, seconds=args.seconds,
                           show=show, show_every_s=0.05)


def serve_command(args: argparse.Namespace) -> int:
    """`pingpong serve`: a match in realtime worker processes, served through the gateway."""
    from dataclasses import replace

    from engine.scene import SceneError, load_scene, with_remote_players
    from engine.world import SimulationError
    from processes.network.gateway import GatewayConfig
    from processes.cli.match import _summary_from_processes
    from processes.supervisor import Supervisor

    try:
        scene = with_remote_players(load_scene(args.scene), args.players)
        if args.best_of is not None:
            if args.best_of < 1 or args.best_of % 2 == 0:
                raise SceneError(f"--best-of must be an odd number >= 1, got {args.best_of}")
            scene = replace(scene, match=replace(scene.match, best_of=args.best_of))
        ticks = scene.ticks if args.ticks is None else args.ticks
        curve = {}
        if getattr(args, "curve_secret", None):
            public, secret = load_curve_key(args.curve_secret, secret=True)
            curve = {"curve_public_key": public, "curve_secret_key": secret}
        config = GatewayConfig(bind=args.bind, snapshot_hz=args.snapshot_hz, timeout_s=args.timeout,
                               grace_s=args.grace, **curve)
        crash = getattr(args, "crash_gateway_at_tick", None)
        supervisor = Supervisor(scene, ticks, "realtime", seed=args.seed, gateway=config,
                                players_timeout=args.wait, crash_at_tick=crash, crash_worker="gateway")

        def ready(reports: dict) -> None:
            endpoint = reports["gateway"]["endpoint"]
            if args.json:
                print(json.dumps({"listening": endpoint, "run_id": supervisor.arena.run_id,
                                  "players": args.players}), flush=True)
            else:
                print(f"serving {scene.name} on {endpoint}: {args.players} remote player(s), "
                      f"{2 - args.players} AI; join with `pingpong join {endpoint} --as player --bot`", flush=True)

        try:
            result = supervisor.run(on_ready=ready)
        except KeyboardInterrupt:
            print("pingpong serve: interrupted; every client was told goodbye", file=sys.stderr)
            return 130
    except (SceneError, SimulationError, ValueError) as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    summary = _summary_from_processes(scene, args.seed, result)
    summary["gateway"] = result.workers.get("gateway", {}).get("gateway", {})
    if args.json:
        print(json.dumps(summary))
    else:
        games = ", ".join(f"{a}-{b}" for a, b in summary["games"]) or "-"
        winner = summary["winner"]
        print(f"{'winner: ' + winner.upper() if winner else 'no winner'}  games: {games}  ticks {summary['ticks']}")
        print("gateway: " + ", ".join(f"{k} {v}" for k, v in summary["gateway"].items()))
    return 0
