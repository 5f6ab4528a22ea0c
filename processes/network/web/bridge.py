"""The web bridge: a gateway client that shows a served match in the browser, in 3D.

A spectator session with the gateway (processes.network.client.client.Client: hello, heartbeats, the
feed) in a thread of its own, and an HTTP + WebSocket server (the `websockets` asyncio library)
in another. The page and its scripts, three.js among them (vendored, see static/vendor),
load from this server only, so it works offline. Every wire message the session takes (the
welcome, snapshots, events, a cloth net's knots, the goodbye) goes unchanged, binary, to every
browser on /ws; a browser that connects late first gets the welcome, the latest snapshot and the
latest net message of each chunk of knots. The page decodes the
wire itself (static/decoder.js), with the layouts of /protocol.json (wire.protocol.layout_json).

A browser may also play: it asks for a seat ({"play": "a"|"b"|"any"}, a JSON text message) and
the bridge opens a player session for it (web.player.BrowserPlayer), a client like `pingpong join
--as player` (run_session with a KeyboardPilot and a Predictor). The browser sends key names ({"key": "up"}: the keys
`join` uses) and pointer aims ({"aim": [x, y, z]}: a point the bat is driven to, kept in the
pilot's reach box); the pilot turns them into force and torque for that seat's bat only, and
the bridge sends the browser its predicted bat ({"predicted": {...}}, about 60 times a second)
beside the wire messages. The gateway decides as for any player: the other bat is out of reach,
a spectator's page can never move one.

Sends to browsers never wait: websockets' broadcast skips a browser whose buffer is full (it
misses that message, the others do not), so a slow browser stalls nobody.
"""
from __future__ import annotations

import asyncio
import json
import mimetypes
import threading

from processes.network import wire
from processes.network.client.client import JOIN_TIMEOUT_S, Client
from processes.network.client.keyboard import KEYS
from processes.network.web import STATIC
from processes.network.web.player import BrowserPlayer
from processes.network.wire import Kind, protocol

PAGES = {"/": "index.html", "/index.html": "index.html", "/app.js": "app.js", "/decoder.js": "decoder.js",
         "/vendor/three.module.min.js": "vendor/three.module.min.js", "/vendor/three.LICENSE": "vendor/three.LICENSE"}
_START_TIMEOUT_S = 10.0
_WRITE_LIMIT = 1 << 20  # bytes buffered per browser before broadcast skips it (about 3000 snapshots)


def parse_host_port(text: str) -> tuple[str, int]:
    """'HOST:PORT' (port 0: any free one) -> (host, port)."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"expected HOST:PORT, got {text!r}")
    return host, int(port)


class WebBridge:
    """The bridge of one gateway's match to any number of browsers.

    Args:
        address: the gateway's session endpoint. web: 'HOST:PORT' of the page and its WebSocket.
        socket_options: for the session and the feed (CURVE keys). name: the spectator's name.
    """

    def __init__(self, address: str, web: str, *, socket_options: dict | None = None, name: str = "web"):
        self.address = address
        self.host, self.port = parse_host_port(web)
        self.socket_options = dict(socket_options or {})
        self.client = Client(address, "spectator", name, socket_options=socket_options)
        self.url = ""
        self.join_timeout_s = JOIN_TIMEOUT_S  # s: the welcome's bound, the bridge's and a browser player's
        self.counts = {"forwarded": 0, "browsers": 0, "browsers_now": 0, "snapshots": 0, "events": 0, "nets": 0}
        self.ended = threading.Event()  # the session is over (goodbye, server lost, or stop())
        self.end_reason = ""
        self._welcome: bytes | None = None
        self._latest: bytes | None = None
        self._nets: dict[int, bytes] = {}  # the latest net message by its first knot (replaced, never changed)
        self._browsers: set = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server = None
        self._stop = threading.Event()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._protocol_json = json.dumps(protocol.layout_json()).encode()
        self._web_thread = threading.Thread(target=self._serve_web, name="web-bridge-http", daemon=True)
        self._session_thread = threading.Thread(target=self._session, name="web-bridge-session", daemon=True)

    # --- lifecycle ---------------------------------------------------------------------------
    def start(self, join_timeout_s: float = JOIN_TIMEOUT_S) -> str:
        """Join the gateway as a spectator (bounded), start the web server; returns its URL.

        Raises:
            Rejected, TimeoutError: the gateway did not take the session. OSError: the web
            address could not be bound.
        """
        self.join_timeout_s = join_timeout_s
        welcome = self.client.join(join_timeout_s)
        self._welcome = self.client.last_data
        self.counts["scene"] = welcome["scene"]
        self._web_thread.start()
        if not self._ready.wait(_START_TIMEOUT_S):
            raise TimeoutError("the web server did not start")
        if self._error is not None:
            raise self._error
        self._session_thread.start()
        return self.url

    def stop(self, timeout_s: float = 5.0) -> None:
        """Leave the gateway (goodbye), close every browser's connection, stop both threads."""
        self._stop.set()
        if self._session_thread.is_alive():
            self._session_thread.join(timeout_s)
        elif not self.ended.is_set():
            self.client.leave()
        loop = self._loop
        if loop is not None and self._web_thread.is_alive():
            loop.call_soon_threadsafe(self._close_server)
            self._web_thread.join(timeout_s)
        self.client.close()
        self.ended.set()

    # --- the gateway side ----------------------------------------------------------------------
    def _session(self) -> None:
        client = self.client
        try:
            while not self._stop.is_set() and client.goodbye is None and not client.server_lost:
                client.heartbeat_if_due()
                message = client.recv(20)
                if message is None:
                    continue
                if message.kind == Kind.SNAPSHOT:
                    self._latest = client.last_data
                    self.counts["snapshots"] += 1
                elif message.kind == Kind.EVENT:
                    self.counts["events"] += 1
                elif message.kind == Kind.NET:
                    self._nets = {**self._nets, message["first"]: client.last_data}
                    self.counts["nets"] += 1
                elif message.kind == Kind.WELCOME:  # a rejoin's welcome (a restarted gateway)
                    self._welcome = client.last_data
                elif message.kind not in (Kind.GOODBYE,):
                    continue  # heartbeats are the session's, not the page's
                self._forward(client.last_data)
            if client.goodbye is None:
                client.leave()
            self.end_reason = client.goodbye.name.lower() if client.goodbye else (
                "server_lost" if client.server_lost else "stopped")
        finally:
            self.ended.set()

    def _forward(self, data: bytes) -> None:
        loop = self._loop
        if loop is not None:
            loop.call_soon_threadsafe(self._broadcast, bytes(data))

    def _broadcast(self, data: bytes) -> None:
        from websockets.asyncio.server import broadcast

        if self._browsers:
            broadcast(self._browsers, data)
            self.counts["forwarded"] += len(self._browsers)

    # --- the browser side ----------------------------------------------------------------------
    def _serve_web(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as err:  # reported to start(); the thread ends
            self._error = err
            self._ready.set()

    async def _main(self) -> None:
        from websockets.asyncio.server import serve

        self._loop = asyncio.get_running_loop()
        self._closed = asyncio.Event()
        async with serve(self._browser, self.host, self.port, process_request=self._http,
                         write_limit=_WRITE_LIMIT, max_size=4096) as server:
            self._server = server
            host, port = next(iter(server.sockets)).getsockname()[:2]
            self.url = f"http://{host}:{port}/"
            self._ready.set()
            await self._closed.wait()

    def _close_server(self) -> None:
        self._closed.set()

    def _http(self, connection, request):
        """Static files and /protocol.json over plain HTTP; /ws goes on to the WebSocket."""
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        path = request.path.split("?", 1)[0]
        if path == "/ws":
            return None
        if path == "/protocol.json":
            body, kind = self._protocol_json, "application/json"
        elif path in PAGES:
            file = STATIC / PAGES[path]
            body = file.read_bytes()
            kind = mimetypes.guess_type(file.name)[0] or "text/plain"
            if file.suffix == ".js":
                kind = "text/javascript"  # module scripts need a JavaScript type
        else:
            return connection.respond(404, f"no such page: {path}\n")
        headers = Headers([("Content-Type", f"{kind}; charset=utf-8"), ("Content-Length", str(len(body))),
                           ("Cache-Control", "no-cache")])
        return Response(200, "OK", headers, body)

    async def _browser(self, websocket) -> None:
        """One browser: the welcome, the latest snapshot and net, then whatever the session brings;
        its requests to play, keys and aims go to its player session (BrowserPlayer)."""
        from websockets.exceptions import ConnectionClosed

        self.counts["browsers"] += 1
        self.counts["browsers_now"] += 1
        player: BrowserPlayer | None = None
        try:
            for data in (self._welcome, self._latest, *self._nets.values()):
                if data is not None:
                    await websocket.send(data)
            self._browsers.add(websocket)
            async for text in websocket:
                request = _request(text)
                if request is None:
                    self.counts["ignored_from_browser"] = self.counts.get("ignored_from_browser", 0) + 1
                elif "play" in request and player is None:
                    player = BrowserPlayer(self, websocket, request["play"])
                    player.start()
                elif player is not None:
                    player.take(request)
                else:  # keys or aims from a browser that plays no seat: it controls nothing
                    self.counts["ignored_from_browser"] = self.counts.get("ignored_from_browser", 0) + 1
        except ConnectionClosed:  # a browser that went away: its connection is over, nothing more
            pass
        finally:
            self._browsers.discard(websocket)
            self.counts["browsers_now"] -= 1
            if player is not None:
                player.stop()

    def send_text(self, websocket, payload: dict) -> None:
        """A JSON text message to one browser, from any thread (dropped once the bridge stops)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        text = json.dumps(payload)

        def send() -> None:
            from websockets.asyncio.server import broadcast

            broadcast([websocket], text)  # never waits: a full browser misses it

        try:
            loop.call_soon_threadsafe(send)
        except RuntimeError:  # the loop closed meanwhile
            pass


def _request(text) -> dict | None:
    """A browser's JSON request, or None for anything else (binary, not JSON, unknown)."""
    if not isinstance(text, str) or len(text) > 512:
        return None
    try:
        request = json.loads(text)
    except ValueError:
        return None
    if not isinstance(request, dict) or len(request) != 1:
        return None
    (name, value), = request.items()
    if name == "play" and value in ("a", "b", "any"):
        return request
    if name == "key" and value in KEYS and value != "quit":
        return request
    if name == "aim" and isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, (int, float)) and abs(v) <= wire.MAX_POS_M for v in value):
        return request
    return None


__all__ = ["PAGES", "WebBridge", "parse_host_port"]
