"""The scene a gateway serves: what its welcomes say of it, and its text for a client that asks."""
from __future__ import annotations

from engine.physics.scene import Scene, scene_digest, scene_toml
from processes.network import wire
from processes.network.server.sessions import Session


class ServedScene:
    """A served engine.physics.scene.Scene as the wire carries it: name, best_of and dt (every welcome),
    its digest (welcome.scene_digest) and its TOML text (engine.physics.scene.scene_toml) cut into
    scene_part messages (`parts`), sent to a session that asks (scene_request)."""

    def __init__(self, scene: Scene):
        self.name = scene.name
        self.best_of = scene.match.best_of
        self.dt = scene.dt
        self.digest = bytes.fromhex(scene_digest(scene))
        self.parts = wire.scene_parts(self.digest, scene_toml(scene))

    def refusal(self, session: Session, digest: bytes) -> str | None:
        """Why a session's scene_request is a bad message (its counter's name), or None: then it is
        counted against the session's MAX_SCENE_REQUESTS and `parts` is the answer."""
        if digest != self.digest:
            return "scene_digest"
        if session.scene_requests >= wire.MAX_SCENE_REQUESTS:
            return "scene_requests"
        session.scene_requests += 1
        return None
