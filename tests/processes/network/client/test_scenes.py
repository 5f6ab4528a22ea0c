"""The served scene on a client (processes.network.client.scenes): sent by the gateway on request,
checked against the welcome's digest, kept by digest; a gateway in this process (the rig fixture)."""
import threading
from dataclasses import replace

import pytest

from engine.physics.scene import SceneError, scene_digest, scene_toml
from processes.network import wire
from processes.network.client.scenes import served_scene
from processes.network.wire import Kind
from tests.helpers.gateway import SCENE
from tests.waits import DEADLINE_S, Deadline


def _fetch(r, client, cache_dir, serve=False):
    """served_scene(client) on a thread of its own while this one pumps the gateway; its Scene (or
    error). serve: snapshots go out, the first before the request is answered (a player's snapshots
    and the scene's parts share its session's socket, in order: the client meets one while it waits)."""
    sent, deadline = r.gateway.counts["snapshots_sent"], Deadline()
    while serve and r.gateway.counts["snapshots_sent"] == sent and not deadline.expired():
        r.publish()
    out = {}

    def run():
        try:
            out["scene"] = served_scene(client, DEADLINE_S, cache_dir)
        except Exception as err:  # handed to the test thread, which raises it
            out["error"] = err

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    deadline = Deadline()
    while thread.is_alive() and not deadline.expired():
        r.step(serve)
    thread.join(DEADLINE_S)
    if "error" in out:
        raise out["error"]
    return out["scene"]


def test_a_client_is_sent_the_served_scene_and_keeps_it_by_digest(rig, tmp_path):
    r = rig()
    player = r.client()
    welcome = r.join(player)
    assert welcome["scene_digest"].hex() == scene_digest(SCENE)
    scene = _fetch(r, player, tmp_path, serve=True)
    assert replace(scene, source=SCENE.source) == SCENE  # every field the server simulates
    assert r.gateway.counts["scene_parts_sent"] == len(r.gateway.served.parts) >= 1
    assert (tmp_path / f"{scene_digest(SCENE)}.toml").read_text() == scene_toml(SCENE)
    kinds = []  # what came while the scene was awaited is still there, in order
    while (message := player.recv(0)) is not None:
        kinds.append(message.kind)
    assert Kind.SNAPSHOT in kinds

    other = r.client(role="spectator")
    r.join(other)
    assert replace(_fetch(r, other, tmp_path), source=SCENE.source) == SCENE
    assert r.gateway.counts["scene_parts_sent"] == len(r.gateway.served.parts)  # from the cache: nothing asked


def test_a_cached_text_that_is_not_the_scene_of_its_digest_is_asked_for_again(rig, tmp_path):
    r = rig()
    player = r.client()
    r.join(player)
    kept = tmp_path / f"{scene_digest(SCENE)}.toml"
    kept.write_text(scene_toml(SCENE).replace("best_of = 1", "best_of = 3"))  # edited: another scene
    assert replace(_fetch(r, player, tmp_path), source=SCENE.source) == SCENE
    assert r.gateway.counts["scene_parts_sent"] == len(r.gateway.served.parts)
    assert kept.read_text() == scene_toml(SCENE)  # replaced by the server's


def test_requests_of_another_digest_or_too_many_are_bad_messages(rig):
    r = rig()
    player = r.client()
    welcome = r.join(player)
    player.send(Kind.SCENE_REQUEST, digest=bytes(wire.DIGEST_SIZE))
    r.settle(lambda: r.gateway.counts["dropped.scene_digest"] == 1)
    for _ in range(wire.MAX_SCENE_REQUESTS + 2):
        player.send(Kind.SCENE_REQUEST, digest=welcome["scene_digest"])
    r.settle(lambda: r.gateway.counts["dropped.scene_requests"] == 2)
    session = next(iter(r.gateway.sessions.values()))
    assert session.bad == 3 and session.scene_requests == wire.MAX_SCENE_REQUESTS
    assert r.gateway.counts["scene_parts_sent"] == wire.MAX_SCENE_REQUESTS * len(r.gateway.served.parts)


def test_a_scene_text_of_another_digest_is_refused_by_name(rig, tmp_path):
    r = rig()
    player = r.client()
    r.join(player)
    wrong = replace(SCENE, match=replace(SCENE.match, best_of=3))
    r.gateway.served.parts = wire.scene_parts(r.gateway.served.digest, scene_toml(wrong))  # a server that lies
    with pytest.raises(SceneError, match=f"sent a scene of digest {scene_digest(wrong)}, not the welcome's"):
        _fetch(r, player, tmp_path)
    assert not list(tmp_path.iterdir())  # nothing kept


def test_parts_join_in_any_order_and_split_characters_whole():
    text = "# " + "卓球" * 1500 + "\n"  # 9004 bytes: three parts, characters cut at 4000 and 8000
    digest = bytes(range(wire.DIGEST_SIZE))
    parts = [wire.decode(data) for data in wire.scene_parts(digest, text)]
    assert [(p["part"], p["parts"]) for p in parts] == [(0, 3), (1, 3), (2, 3)]
    assembly = wire.SceneAssembly(digest)
    assert assembly.add(parts[2]) is None and assembly.add(parts[0]) is None
    assert assembly.add(parts[1]) == text
    with pytest.raises(wire.OutOfRange, match="scene_part.digest"):
        wire.SceneAssembly(bytes(wire.DIGEST_SIZE)).add(parts[0])
    with pytest.raises(ValueError, match="more than the 64000"):
        wire.scene_parts(digest, "x" * (wire.MAX_SCENE_PARTS * wire.SCENE_CHUNK + 1))
