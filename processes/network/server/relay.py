"""The relay: a ZeroMQ proxy that re-publishes a gateway's spectator feed to more subscribers.

An XSUB socket connects to the gateway's feed (its PUB: the endpoint `pingpong serve` reports
as "feed", the session's host with welcome.feed_port), an XPUB socket binds where the relay's
subscribers connect, and libzmq's own proxy (zmq_proxy) moves the messages one way and
the subscriptions the other, in its C loop: one subscription upstream, whatever the number of
subscribers downstream, so spectators and web bridges on other machines fan out without loading
the gateway. The bytes are the feed's own (same header seq stream, so a subscriber still counts
gaps); the relay drops a slow subscriber's newest messages at its SNDHWM, like the feed.

A relay carries the feed only: sessions (hello, heartbeats, goodbye) stay between each client
and the gateway.
"""
from __future__ import annotations

import threading

import zmq

from processes.network.wire import MAX_FRAME_BYTES

RELAY_SNDHWM = 1000  # messages queued per subscriber (the gateway's feed queues 32): a relay is a buffer
_START_TIMEOUT_S = 10.0


class Relay:
    """One XSUB -> XPUB proxy in a thread of its own, on a ZeroMQ context of its own: stop()
    terminates the context, the proxy returns (ETERM) and the thread closes the sockets.

    Args:
        upstream: the feed's endpoint (tcp://host:port). bind: where subscribers connect; port
            0 picks a free one (see `endpoint` after start()).
        sndhwm: messages queued per subscriber before its newest are dropped.
        socket_options: {zmq option: value} for the upstream socket (e.g. CURVE keys).
    """

    def __init__(self, upstream: str, bind: str, *, sndhwm: int = RELAY_SNDHWM, socket_options: dict | None = None):
        self.upstream = upstream
        self.bind = bind
        self.sndhwm = sndhwm
        self.socket_options = dict(socket_options or {})
        self.endpoint = ""
        self.zctx = zmq.Context()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="relay", daemon=True)

    def start(self) -> str:
        """Bind, connect and start proxying; returns the bound endpoint."""
        self._thread.start()
        if not self._ready.wait(_START_TIMEOUT_S):
            raise TimeoutError("the relay's sockets did not start")
        if self._error is not None:
            self._thread.join(_START_TIMEOUT_S)
            raise self._error
        return self.endpoint

    def _run(self) -> None:
        xsub = self.zctx.socket(zmq.XSUB)
        xpub = self.zctx.socket(zmq.XPUB)
        try:
            try:
                for sock in (xsub, xpub):
                    sock.setsockopt(zmq.LINGER, 0)
                for option, value in self.socket_options.items():
                    xsub.setsockopt(option, value)
                xpub.setsockopt(zmq.SNDHWM, self.sndhwm)
                xpub.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)  # what a subscriber may send: subscriptions
                xpub.bind(self.bind[:-2] + ":*" if self.bind.endswith(":0") else self.bind)
                self.endpoint = xpub.getsockopt_string(zmq.LAST_ENDPOINT)
                xsub.connect(self.upstream)
            except zmq.ZMQError as err:
                self._error = err
                return
            finally:
                self._ready.set()
            try:
                zmq.proxy(xsub, xpub)
            except zmq.ContextTerminated:  # stop()
                pass
        finally:
            xsub.close(linger=0)
            xpub.close(linger=0)

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the proxy: terminate the context (it waits for the thread to close its sockets)."""
        terminator = threading.Thread(target=self.zctx.term, name="relay-term", daemon=True)
        terminator.start()
        terminator.join(timeout_s)
        self._thread.join(timeout_s)
        if terminator.is_alive() or self._thread.is_alive():
            raise TimeoutError("the relay's proxy did not terminate")
