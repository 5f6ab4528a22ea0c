"""A recorded match as one offline page: the wire messages a spectator would have got, in 3D."""
from __future__ import annotations

import base64
import html
import json

import numpy as np

from engine.physics.scene import SceneError, scene_digest, scene_from_toml
from processes.network import wire
from processes.network.web import STATIC
from processes.network.wire import Kind, protocol


def _digest(text: str, name: str) -> bytes:
    """The recorded scene's digest (its TOML text, engine.physics.scene.scene_toml), zeros if the replay
    carries none that reads as a scene (an older file)."""
    try:
        return bytes.fromhex(scene_digest(scene_from_toml(text, name)))
    except SceneError:
        return bytes(wire.DIGEST_SIZE)


def replay_messages(replay, best_of: int) -> list[bytes]:
    """The wire messages a spectator would have got of a recorded match (engine.tools.replay.Replay):
    a welcome, a snapshot per frame, a point event per decided rally (and a game and a match
    event where it decided one), in tick order."""
    header, frames = replay.header, replay.frames
    out = [wire.encode(Kind.WELCOME, tick=0, slot=wire.Slot.NONE, best_of=best_of, snapshot_hz=max(1, min(1000, round(
        1.0 / (header["dt"] * max(1, header["frame_every"]))))), heartbeat_ms=500, timeout_ms=5000, dt=header["dt"],
        token=bytes(wire.TOKEN_SIZE), scene=header["scene"][:32], name_a="A", name_b="B", feed_port=0,
        scene_digest=_digest(header.get("scene_toml", ""), header["scene"]))]
    timed = []
    for frame in frames:
        try:
            timed.append((int(frame["world"]["tick"]), 0, wire.snapshot_from_physics(frame, seq=len(timed) + 1)))
        except wire.WireError:  # a frame the wire cannot carry (never written, or beyond its ranges)
            continue
    ticks = frames["world"]["tick"] if len(frames) else np.zeros(0, np.int64)
    games = np.zeros(2, np.int64)
    for k, row in enumerate(replay.points):
        tick = int(row["tick"])
        after = int(np.searchsorted(ticks, tick + 1))  # the first frame after the rally: its games_won
        frame = frames[min(after, len(frames) - 1)] if len(frames) else None
        won = frame["rally"]["games_won"] if frame is not None else games
        rally = int(frame["rally"]["rally"]) if frame is not None else k + 1
        fields = dict(winner=int(row["winner"]), reason=int(row["reason"]), game=int(row["game"]),
                      score=row["score_after"], games_won=won, shots=int(row["shots"]), rally=rally)
        timed.append((tick, 1, wire.encode(Kind.EVENT, tick=tick, event=wire.EventKind.POINT, **fields)))
        if tuple(won) != tuple(games):
            timed.append((tick, 2, wire.encode(Kind.EVENT, tick=tick, event=wire.EventKind.GAME, **fields)))
            games = np.array(won)
        if k == len(replay.points) - 1 and header.get("summary", {}).get("winner"):
            timed.append((tick, 3, wire.encode(Kind.EVENT, tick=tick, event=wire.EventKind.MATCH, **fields)))
    timed.sort(key=lambda item: item[:2])
    return out + [data for *_, data in timed]


def replay_page(messages: list[bytes], title: str) -> str:
    """One self-contained HTML page that plays `messages` (a welcome, snapshots, events) in 3D:
    three.js, the decoder, the app and the protocol's layouts inlined (base64), nothing fetched."""
    def b64(data: bytes) -> str:
        return base64.b64encode(data).decode("ascii")

    page = (STATIC / "index.html").read_text()
    loader = f"""<script type="text/plain" id="three-src">{b64((STATIC / 'vendor/three.module.min.js').read_bytes())}</script>
<script type="text/plain" id="decoder-src">{b64((STATIC / 'decoder.js').read_bytes())}</script>
<script type="text/plain" id="app-src">{b64((STATIC / 'app.js').read_bytes())}</script>
<script type="application/json" id="protocol">{json.dumps(protocol.layout_json())}</script>
<script type="application/json" id="messages">{json.dumps([b64(m) for m in messages])}</script>
<script type="module">
  const bytes = (id) => Uint8Array.from(atob(document.getElementById(id).textContent), (c) => c.charCodeAt(0));
  const url = (data) => URL.createObjectURL(new Blob([data], {{ type: "text/javascript" }}));
  const three = url(bytes("three-src")), decoder = url(bytes("decoder-src"));
  const app = new TextDecoder().decode(bytes("app-src"))
    .replace('"./vendor/three.module.min.js"', JSON.stringify(three)).replace('"./decoder.js"', JSON.stringify(decoder));
  const {{ startReplay }} = await import(url(app));
  startReplay(JSON.parse(document.getElementById("protocol").textContent),
              JSON.parse(document.getElementById("messages").textContent));
</script>"""
    live = page[page.index('<script type="module">'):page.index("</script>", page.index('<script type="module">')) + 9]
    page = page.replace(live, loader).replace("<title>pingpong</title>", f"<title>{html.escape(title)}</title>")
    return page.replace('<div id="status">connecting ...</div>', '<div id="status">replay</div>')


__all__ = ["replay_messages", "replay_page"]
