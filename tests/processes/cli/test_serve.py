"""`pingpong serve`, `join`, `watch` and `relay` as processes: a served match, its clients, its end.

The servers run in sessions of their own (the served fixture stops and reaps them, whatever
happened); every line awaited within the suite's deadline (tests/waits.py).
"""
import json
import os
import signal
import time

from processes.runtime import shm
from processes.network.client.client import Client
from processes.network.wire import Kind
from tests.helpers.commands import ROOT, pingpong
from tests.waits import DEADLINE_S, Deadline, line, rest


def test_serve_web_shows_the_page_beside_the_match(served):
    import urllib.request

    server = pingpong("serve", "--players", "0", "--ticks", "600000", "--web", "127.0.0.1:0", "--json")
    served.append(server)
    assert "listening" in json.loads(line(server, "the server's listening line"))
    url = json.loads(line(server, "the web bridge's line"))["web"]  # the bridge joined as a spectator, serves the page
    with urllib.request.urlopen(url, timeout=DEADLINE_S) as reply:
        assert reply.status == 200 and b"app.js" in reply.read()
    os.kill(server.pid, signal.SIGINT)
    assert server.wait(DEADLINE_S) == 130
    interrupted = json.loads(rest(server, "the server's counters").strip().splitlines()[-1])
    assert interrupted["gateway"]["spectators_joined"] == 1  # the bridge, a gateway client like any other


def test_watch_smoke_runs(served):
    lonely = pingpong("watch", "tcp://127.0.0.1:9", "--web", "127.0.0.1:0", "--join-timeout", "0.5")
    served.append(lonely)
    assert lonely.wait(DEADLINE_S) == 4 and "no welcome" in lonely.stderr.read()  # nobody there: no welcome in time
    bad = pingpong("watch", "tcp://127.0.0.1:9", "--web", "8080")
    served.append(bad)
    assert bad.wait(DEADLINE_S) == 2 and "HOST:PORT" in bad.stderr.read()


def test_relay_smoke_runs(served):
    relay = pingpong("relay", "tcp://127.0.0.1:9", "--bind", "tcp://127.0.0.1:0", "--seconds", "0.2", "--json")
    served.append(relay)
    said = json.loads(line(relay, "the relay's listening line"))
    assert said["relaying"] == "tcp://127.0.0.1:9" and said["listening"].startswith("tcp://127.0.0.1:")
    assert relay.wait(DEADLINE_S) == 0


def test_two_bot_players_and_a_spectator_play_a_served_match(served, tmp_path, scene_cache):
    # A scene of the server's own, unknown to the clients by name: they play it from its text.
    mine = tmp_path / "mine.toml"
    mine.write_text((ROOT / "scenes" / "match.toml").read_text().replace('name = "match"', 'name = "mine"'))
    server = pingpong("serve", "--scene", str(mine), "--players", "2", "--best-of", "1", "--ticks", "2500",
                      "--snapshot-hz", "100", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    endpoint = hello["listening"]
    assert endpoint.startswith("tcp://127.0.0.1:")
    # the clients leave at the match's end; --seconds is only their own safety net
    # one player of the bot API from its file, one AI profile: the same door (engine.play.players' seat)
    bots = [pingpong("join", endpoint, "--as", "player", "--bot", *player, "--json", "--seconds", f"{DEADLINE_S:.0f}")
            for player in (["examples/attack.py:Attack"], [])]
    served.extend(bots)
    spectator = pingpong("join", endpoint, "--as", "spectator", "--json", "--seconds", f"{DEADLINE_S:.0f}")
    served.append(spectator)
    summary = json.loads(line(server, "the server's summary"))
    assert server.wait(DEADLINE_S) == 0
    reports = [json.loads(line(p, "a client's report")) for p in (*bots, spectator)]
    assert sorted(r["slot"] for r in reports) == ["a", "b", "none"]
    assert {r["scene"] for r in reports} == {"mine"}
    digest = reports[0]["scene_digest"]
    assert (scene_cache / f"{digest}.toml").exists()  # the bots were sent the scene and kept it
    for report in reports:
        assert report["goodbye"] == "match_over", report
        assert report["snapshots"] > 0 and report["dropped"] == {}
    assert [r["bot"]["player"] for r in reports[:2]] == ["examples/attack.py:Attack", "pro"]
    assert reports[0]["bot"]["decisions"] > 0 and reports[0]["bot_errors"] == []
    for bot in reports[:2]:  # the physics applied this bot's inputs: the snapshots echo their seq
        assert bot["inputs_sent"] > 0 and bot["input_seq"]["ab".index(bot["slot"])] > 0
        prediction = bot["prediction"]  # each bot predicted and scored its prediction on the snapshots
        assert prediction["scored"] > 0 and prediction["ball"]["n"] == prediction["bat"]["n"] == prediction["scored"], bot
        assert prediction["ball"]["max_mm"] >= prediction["ball"]["p99_mm"] >= prediction["ball"]["p50_mm"] >= 0.0
    assert reports[2]["interpolation"]["samples"] > 0  # the spectator's view was interpolated
    gateway = summary["gateway"]
    assert summary["ticks"] == 2500 or summary["winner"] is not None
    assert gateway["players_joined"] == 2 and gateway["spectators_joined"] == 1
    # every accepted input is one a bot sent (how many a loaded machine lets a bot send is not a
    # promise; that the physics applied each bot's is, by the input_seq above)
    sent = sum(bot["inputs_sent"] for bot in reports[:2])
    assert 2 <= gateway["inputs_accepted"] <= sent, (gateway["inputs_accepted"], sent)
    assert gateway.get("refused.other_bat", 0) == 0
    assert gateway["goodbyes_at_end"] == 3 and gateway["dropped_total"] == 0
    assert not shm.leftover_segments(hello["run_id"])


def test_serve_and_join_smoke_runs(served):
    server = pingpong("serve", "--players", "0", "--ticks", "2", "--json")
    served.append(server)
    # The first line comes once the workers are ready: on a cold numba cache they compile first.
    assert json.loads(line(server, "the server's listening line"))["players"] == 0
    summary = json.loads(line(server, "the server's summary"))
    assert summary["ticks"] == 2 and summary["gateway"]["goodbyes_at_end"] == 0
    assert server.wait(DEADLINE_S) == 0
    lonely = pingpong("join", "tcp://127.0.0.1:9", "--as", "spectator", "--join-timeout", "0.5")
    served.append(lonely)
    assert lonely.wait(DEADLINE_S) == 4  # nobody there: no welcome in time
    keyboard = pingpong("join", "tcp://127.0.0.1:9", "--as", "player")
    served.append(keyboard)
    assert keyboard.wait(DEADLINE_S) == 2 and "keyboard" in keyboard.stderr.read()


def test_serve_tells_how_to_join_what_it_serves():
    from processes.cli.serve import _serving_line

    assert "--as player" not in _serving_line("match", "tcp://127.0.0.1:1", 0)  # nobody to play: watch
    assert "--as spectator" in _serving_line("match", "tcp://127.0.0.1:1", 0)
    assert "--as player" in _serving_line("match", "tcp://127.0.0.1:1", 1)


def _ticks_seen(client, count):
    """The ticks of the next `count` snapshots `client` gets (heartbeating; within the deadline)."""
    ticks, deadline = [], Deadline()
    while not deadline.expired():
        client.heartbeat_if_due()
        message = client.recv(100)
        if message is not None and message.kind == Kind.SNAPSHOT:
            ticks.append(message.tick)
            if len(ticks) == count:
                return ticks
    raise AssertionError(f"{len(ticks)} snapshots of {count} within {DEADLINE_S:.0f} s")


def test_a_served_match_waits_for_its_player_and_pauses_while_the_seat_is_in_its_grace(served, zctx):
    server = pingpong("serve", "--players", "1", "--ticks", "600000", "--timeout", "1", "--grace", "60", "--json")
    served.append(server)
    endpoint = json.loads(line(server, "the server's listening line"))["listening"]
    watcher = Client(endpoint, "spectator", "sp", zctx=zctx)
    player = Client(endpoint, "player", "ann", zctx=zctx)
    try:
        watcher.join(DEADLINE_S)
        assert set(_ticks_seen(watcher, 30)) == {0}  # nobody on seat A: no serve, the clock stands
        token = player.join(DEADLINE_S)["token"]
        deadline = Deadline()
        while not deadline.expired():  # the match starts: the ticks move
            player.heartbeat_if_due()
            player.recv(0)
            if _ticks_seen(watcher, 1)[0] > 0:
                break
        else:
            raise AssertionError("the match never started")
        # the player falls silent: dropped after the 1 s timeout, its seat in its grace, the match paused
        deadline = Deadline()
        while not deadline.expired():
            window = _ticks_seen(watcher, 30)
            if len(set(window)) == 1:
                break
        else:
            raise AssertionError("the match never paused")
        paused_at = window[0]
        assert paused_at > 0
        player.token = token
        player.hello()  # back with the token: the match goes on from where it stood
        deadline = Deadline()
        while not deadline.expired():
            message = player.recv(100)
            if message is not None and player.accept(message):
                break
        else:
            raise AssertionError("no welcome back")
        deadline = Deadline()
        while not deadline.expired():
            player.heartbeat_if_due()
            player.recv(0)
            tick = _ticks_seen(watcher, 1)[0]
            if tick > paused_at:
                break
        assert tick > paused_at
    finally:
        watcher.close()
        player.close()
