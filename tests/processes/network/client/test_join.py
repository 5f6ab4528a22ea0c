"""Client.join says hello again while unanswered: a hello lost with a connection the server cut
(at its connection limit) is never answered, and libzmq does not resend what the kernel took.

A bare ROUTER in this test plays the server and drops the first hello; every wait bounded.
"""
import threading

import zmq

from processes.network import wire
from processes.network.client.client import Client
from processes.network.wire import Kind
from tests.helpers.golden import GOLDEN_FIELDS
from tests.waits import DEADLINE_S


def test_join_says_hello_again_until_it_is_answered(zctx):
    router = zctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    client = Client(f"tcp://127.0.0.1:{port}", "player", "ann", zctx=zctx)
    joined = {}
    joining = threading.Thread(target=lambda: joined.update(welcome=client.join(DEADLINE_S)), daemon=True)
    joining.start()
    try:
        hellos = []
        while len(hellos) < 2 and router.poll(int(DEADLINE_S * 1000)):
            identity, data = router.recv_multipart()
            hellos.append(wire.decode(data))  # the first one is dropped: as if its connection was cut
        kind, fields = GOLDEN_FIELDS["welcome_a"]
        router.send_multipart([identity, wire.encode(kind, **fields)])
        joining.join(DEADLINE_S)
        assert [m.kind for m in hellos] == [Kind.HELLO, Kind.HELLO] and hellos[1].seq > hellos[0].seq
        assert joined["welcome"].kind == Kind.WELCOME and client.welcome is not None
    finally:
        client.close()
        router.close()
