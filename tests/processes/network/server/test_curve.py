"""CURVE: an encrypted session and feed, and a client without the server's key cannot join.
"""
import json

import pytest
import zmq

from processes.network.wire import Kind, Slot


# --- CURVE ------------------------------------------------------------------------------------
def _unanswered(r, client, rounds=40):
    """True if the client hears nothing while the gateway is pumped `rounds` times (bounded)."""
    client.hello()
    for _ in range(rounds):
        r.step(serve=True)
        if client.recv(10) is not None:
            return False
    return True


def test_a_curve_session_works_and_a_client_without_the_server_key_cannot_join(rig, zctx, tmp_path):
    import zmq.auth

    from processes.cli import main
    from processes.network.client.client import curve_client_options, load_curve_key

    assert main(["keys", str(tmp_path / "keys"), "--json"]) == 0  # `pingpong keys DIR`
    public_file, secret_file = tmp_path / "keys" / "server.key", tmp_path / "keys" / "server.key_secret"
    public, secret = load_curve_key(str(secret_file), secret=True)
    r = rig(curve_secret_key=secret, curve_public_key=public)
    good = r.client(name="ann", socket_options=curve_client_options(str(public_file)))
    assert r.join(good)["slot"] == Slot.A
    snapshot = r.until(good, lambda m: m.kind == Kind.SNAPSHOT, serve=True)
    assert snapshot["winner"] == -1
    (tmp_path / "other").mkdir()
    other_public, _ = zmq.auth.create_certificates(str(tmp_path / "other"), "server")
    wrong = r.client(name="eve", socket_options=curve_client_options(other_public))
    assert _unanswered(r, wrong)  # its handshake fails: no message either way
    plain = r.client(name="bob")  # no CURVE at all
    assert _unanswered(r, plain)
    assert len(r.gateway.sessions) == 1
    assert r.gateway.stats()["players_joined"] == 1
    # the feed is a CURVE server too: a spectator with the key watches there, a SUB without it gets nothing
    watcher = r.client(role="spectator", name="sam", socket_options=curve_client_options(str(public_file)))
    assert r.join(watcher)["feed_port"] == r.gateway.feed_port > 0
    snapshot = r.until(watcher, lambda m: m.kind == Kind.SNAPSHOT, serve=True)
    assert watcher.feed_seq == snapshot.seq > 0  # it came on the feed
    eavesdropper = zctx.socket(zmq.SUB)
    eavesdropper.setsockopt(zmq.SUBSCRIBE, b"")
    eavesdropper.connect(r.gateway.feed_endpoint)
    for _ in range(40):
        r.step(serve=True)
        assert not eavesdropper.poll(10, zmq.POLLIN)
    assert r.until(watcher, lambda m: m.kind == Kind.SNAPSHOT, serve=True).seq > snapshot.seq  # still served
    with pytest.raises(ValueError, match="no secret key"):
        load_curve_key(str(public_file), secret=True)
    with pytest.raises(ValueError, match="not a ZeroMQ certificate"):
        load_curve_key(str(tmp_path / "missing.key"), secret=False)
