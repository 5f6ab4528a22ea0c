"""The served scene on the wire: its TOML text cut into scene_part messages, and joined again."""
from __future__ import annotations

from processes.network.wire.checks import OutOfRange
from processes.network.wire.codec import Message, encode
from processes.network.wire.messages import DIGEST_SIZE, MAX_SCENE_PARTS, SCENE_CHUNK, Kind


def scene_parts(digest: bytes, text: str, tick: int = 0) -> list[bytes]:
    """The scene_part messages of one scene's TOML `text` (engine.physics.scene.scene_toml) with its
    digest (the welcome's scene_digest). Raises ValueError for a text beyond MAX_SCENE_PARTS parts."""
    raw = text.encode("utf-8")
    if not raw or len(digest) != DIGEST_SIZE:
        raise ValueError(f"a scene needs text and a {DIGEST_SIZE}-byte digest; got {len(raw)} bytes, digest {digest!r}")
    chunks = [raw[at:at + SCENE_CHUNK] for at in range(0, len(raw), SCENE_CHUNK)]
    if len(chunks) > MAX_SCENE_PARTS:
        raise ValueError(f"the scene's TOML text is {len(raw)} bytes, more than the {MAX_SCENE_PARTS * SCENE_CHUNK} "
                         "that scene_part messages carry")
    return [encode(Kind.SCENE_PART, tick=tick, digest=digest, part=i, parts=len(chunks), size=len(chunk),
                   text=chunk.ljust(SCENE_CHUNK, b"\0")) for i, chunk in enumerate(chunks)]


class SceneAssembly:
    """Collects the scene_part messages of the scene with `digest` into its text.

    add() takes each (in any order; a repeated part replaces the one before); `text` is the
    whole UTF-8 text once every part has come, else None. A part of another digest, or one
    whose count of parts disagrees with the first's, raises OutOfRange (a server that
    mixes two scenes: the client names it and stops)."""

    def __init__(self, digest: bytes):
        self.digest = digest
        self.parts: dict[int, bytes] = {}
        self.count = 0

    def add(self, message: Message) -> str | None:
        if message["digest"] != self.digest:
            raise OutOfRange(f"scene_part.digest: {message['digest'].hex()}, the welcome's is {self.digest.hex()}")
        if self.count and message["parts"] != self.count:
            raise OutOfRange(f"scene_part.parts: {message['parts']}, an earlier part said {self.count}")
        self.count = message["parts"]
        self.parts[message["part"]] = message["text"][:message["size"]]
        return self.text

    @property
    def text(self) -> str | None:
        if not self.count or len(self.parts) < self.count:
            return None
        raw = b"".join(self.parts[i] for i in range(self.count))
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as err:
            raise OutOfRange(f"scene_part.text: the joined parts are not UTF-8 ({err})") from None
