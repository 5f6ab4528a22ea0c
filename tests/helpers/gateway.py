"""A Gateway in the test's own process on 127.0.0.1, its clients, a clock the test sets (Rig), and
the waits on a client's messages that several rooms' tests share."""
from dataclasses import replace

import numpy as np

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.scene import load_scene
from processes.network.client.client import Client
from processes.network.server.config import GatewayConfig
from processes.network.server.gateway import Gateway
from processes.network.wire import Kind, Slot
from tests.waits import DEADLINE_S, Deadline

# The served scene: the rigid match, best of 1 (the gateway reads only its name, best_of, dt and text).
SCENE = replace(load_scene("match_rigid"), match=replace(load_scene("match_rigid").match, best_of=1))
ROUNDS = 400  # pump rounds of a bounded exchange (each polls for at most 10 ms)


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class Rig:
    """A Gateway on a random port of 127.0.0.1, its clients, and a physics record to serve."""

    def __init__(self, zctx, remote=(Slot.A, Slot.B), seat_store=None, clock=None, **config):
        self.zctx = zctx
        self.clock = Clock() if clock is None else clock
        self.posted = []
        settings = dict(bind="tcp://127.0.0.1:0", snapshot_hz=1000, heartbeat_s=1.0, timeout_s=5.0, grace_s=30.0)
        settings.update(config)
        self.gateway = Gateway(zctx, GatewayConfig(**settings), scene=SCENE, remote_slots=remote, post_input=self._post, clock=self.clock, seat_store=seat_store)
        self.record = np.zeros(1, physics_snapshot_dtype(2))[0]
        self.record["bats"]["quat"] = (1.0, 0.0, 0.0, 0.0)
        self.record["rally"]["winner"] = -1
        self.clients = []

    def _post(self, bat, seq, tick, inputs):
        self.posted.append((bat, seq, tick, np.array(inputs)))
        return True

    def client(self, role="player", slot=Slot.NONE, token=bytes(16), name="p", socket_options=None) -> Client:
        client = Client(self.gateway.endpoint, role, name, slot, token, zctx=self.zctx, socket_options=socket_options)
        self.clients.append(client)
        return client

    def step(self, serve=False):
        self.gateway.poll(2)
        if serve:
            self.publish()
        else:
            self.gateway.service(None)

    def publish(self):
        """A snapshot of the record on the feed (a subscriber that is still connecting misses the first ones)."""
        self.clock.now += 1.0 / self.gateway.config.snapshot_hz
        self.gateway.service(self.record)

    def until(self, client, predicate, serve=False):
        """Pump gateway and client until the client gets a message satisfying predicate (within the deadline)."""
        deadline, last = Deadline(), None
        while not deadline.expired():
            self.step(serve)
            message = client.recv(5)
            if message is not None:
                if predicate(message):
                    return message
                last = message
        raise AssertionError(f"no such message within {DEADLINE_S:.0f} s; the last one: {last}")

    def settle(self, check):
        """Pump the gateway until check() holds (within the deadline)."""
        deadline = Deadline()
        while not deadline.expired():
            self.step()
            if check():
                return
        raise AssertionError(f"the gateway never got there within {DEADLINE_S:.0f} s; counts: {self.gateway.counts}")

    def join(self, client):
        """Hello, welcome, and the client's first heartbeat received: the session is confirmed
        before the test moves the clock."""
        client.hello()
        message = self.until(client, lambda m: m.kind in (Kind.WELCOME, Kind.REJECT))
        beats = self.gateway.counts["heartbeats_received"]
        client.accept(message)
        self.settle(lambda: self.gateway.counts["heartbeats_received"] > beats)
        return message

    def close(self):
        for client in self.clients:
            client.close()
        self.gateway.close()


def first_tick(client, tick):
    deadline = Deadline()
    while not deadline.expired():
        message = client.recv(10)
        if message is not None and message.kind == Kind.SNAPSHOT and message.tick == tick:
            return message
    raise AssertionError(f"no snapshot of tick {tick} within {DEADLINE_S:.0f} s")


def until_goodbye(client):
    """Heartbeat and read until the server's goodbye (None if it never came within the deadline); the snapshot ticks seen."""
    ticks, deadline = [], Deadline()
    while not deadline.expired():
        client.heartbeat_if_due()
        message = client.recv(100)
        if message is not None and message.kind == Kind.GOODBYE:
            return message, ticks
        if message is not None and message.kind == Kind.SNAPSHOT:
            ticks.append(message.tick)
    return None, ticks
