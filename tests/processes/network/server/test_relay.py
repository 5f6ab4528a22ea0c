"""The relay: the gateway's feed re-published byte for byte (processes.network.server.relay).
"""
import zmq

from processes.network import wire
from tests.helpers.gateway import ROUNDS, first_tick
from tests.waits import DEADLINE_S, Deadline


def test_a_relay_republishes_the_feed_byte_for_byte_to_its_subscribers(rig, zctx):
    from processes.network.server.relay import Relay

    r = rig()
    watcher = r.client(role="spectator")
    r.join(watcher)  # a spectator of the gateway itself, to compare with
    relay = Relay(r.gateway.feed_endpoint, "tcp://127.0.0.1:0")
    endpoint = relay.start()
    subscribers = []
    try:
        for _ in range(2):
            sub = zctx.socket(zmq.SUB)
            sub.setsockopt(zmq.LINGER, 0)
            sub.setsockopt(zmq.SUBSCRIBE, b"")
            sub.connect(endpoint)
            subscribers.append(sub)
        tick = 0
        got = [None, None]
        deadline = Deadline()
        while not deadline.expired():  # serve ticks until both relayed subscriptions are live
            tick += 1
            r.record["world"]["tick"] = tick
            r.clock.now += 0.002
            r.gateway.service(r.record)
            for i, sub in enumerate(subscribers):
                if got[i] is None and sub.poll(5, zmq.POLLIN):
                    got[i] = sub.recv()
            if all(got):
                break
        assert all(got), "the relay forwarded nothing"
        later = tick + 1  # one more snapshot: every subscriber gets exactly the feed's bytes
        r.record["world"]["tick"] = later
        r.clock.now += 0.002
        r.gateway.service(r.record)
        relayed = []
        for sub in subscribers:
            for _ in range(ROUNDS):
                assert sub.poll(int(1000 * DEADLINE_S), zmq.POLLIN), f"the relay lost the snapshot of tick {later}"
                data = sub.recv()
                if wire.decode(data).tick == later:
                    relayed.append(data)
                    break
        direct = first_tick(watcher, later)
        direct_bytes = wire.encode(direct.kind, seq=direct.seq, tick=direct.tick, flags=direct.flags, **direct.fields)
        assert relayed[0] == relayed[1] == direct_bytes  # the feed's own bytes, its seq included
    finally:
        for sub in subscribers:
            sub.close(linger=0)
        relay.stop()
