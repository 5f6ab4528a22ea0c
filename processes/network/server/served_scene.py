"""The scene a gateway serves: what its welcomes say of it, and its text for a client that asks."""
from __future__ import annotations

from engine.physics.compiled import CompiledScene
from processes.network import wire
from processes.network.server.sessions import Session


class ServedScene:
    """A served scene (engine.physics.compiled.CompiledScene) as the wire carries it: name, best_of
    and dt (every welcome), its digest (welcome.scene_digest) and its TOML text
    (engine.physics.scene.scene_toml) cut into scene_part messages (`parts`), sent to a session
    that asks (scene_request)."""

    def __init__(self, compiled: CompiledScene):
        self.name = compiled.scene.name
        self.best_of = compiled.scene.match.best_of
        self.dt = compiled.dt
        self.digest = bytes.fromhex(compiled.digest)
        self.parts = wire.scene_parts(self.digest, compiled.toml)

    def refusal(self, session: Session, digest: bytes) -> str | None:
        """Why a session's scene_request is a bad message (its counter's name), or None: then it is
        counted against the session's MAX_SCENE_REQUESTS and `parts` is the answer."""
        if digest != self.digest:
            return "scene_digest"
        if session.scene_requests >= wire.MAX_SCENE_REQUESTS:
            return "scene_requests"
        session.scene_requests += 1
        return None
