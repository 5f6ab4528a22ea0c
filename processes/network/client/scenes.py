"""The served scene on a client: the one its welcome names by digest, from the client's cache or
asked of the server, so a client predicts with exactly the server's physics.

The cache keeps each scene's TOML text (engine.physics.scene.scene_toml) as DIGEST.toml in
$PINGPONG_SCENE_CACHE, else $XDG_CACHE_HOME/pingpong/scenes, else ~/.cache/pingpong/scenes. A
cached text is used only if it still reads as a scene of that digest (a file edited, or written
by a version whose scenes mean something else, is asked for again and replaced).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from engine.physics.scene import Scene, SceneError, scene_digest, scene_from_toml
from processes.network import wire
from processes.network.client.client import JOIN_TIMEOUT_S, Client

CACHE_ENV = "PINGPONG_SCENE_CACHE"


def scene_cache_dir() -> Path:
    """Where served scenes are kept (see the module's docstring)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "pingpong" / "scenes"


def served_scene(client: Client, timeout_s: float = JOIN_TIMEOUT_S, cache_dir: Path | None = None) -> Scene:
    """The scene of the client's welcome (its scene_digest): cached, or asked of the server
    (Client.request_scene) and then cached.

    Raises:
        TimeoutError: the server did not send it within timeout_s.
        SceneError: the server's text is not a scene, or not the scene of the welcome's digest.
    """
    welcome = client.welcome
    digest = welcome["scene_digest"].hex()
    source = f"scene {welcome['scene']!r} served by {client.address} (digest {digest})"
    folder = scene_cache_dir() if cache_dir is None else Path(cache_dir)
    path = folder / f"{digest}.toml"
    try:
        scene = scene_from_toml(path.read_text(encoding="utf-8"), source)
        if scene_digest(scene) == digest:
            return scene
    except (OSError, UnicodeDecodeError, SceneError):
        pass  # not cached, or not usable: ask the server
    try:
        text = client.request_scene(timeout_s)
    except wire.WireError as err:
        raise SceneError(f"{source}: the server's scene_part messages do not fit together: {err}") from None
    scene = scene_from_toml(text, source)
    if scene_digest(scene) != digest:
        raise SceneError(f"{source}: the server sent a scene of digest {scene_digest(scene)}, not the welcome's; "
                         "the server is inconsistent (a different version?)")
    _keep(path, text)
    return scene


def _keep(path: Path, text: str) -> None:
    """Write the cache file atomically (a reader never sees half of it); a cache that cannot be
    written (a read-only home) only costs the next join a request."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", encoding="utf-8", dir=path.parent, suffix=".part",
                                         delete=False) as out:
            out.write(text)
        os.replace(out.name, path)
    except OSError:
        pass
