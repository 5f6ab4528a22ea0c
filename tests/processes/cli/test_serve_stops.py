"""How a served match stops: Ctrl-C, SIGTERM, a killed gateway restarted, a failing worker past its budget.

`pingpong serve` runs in a session of its own (the served fixture stops and reaps it); every wait
bounded by the suite's deadline, and nothing (processes, shared memory) is left behind.
"""
import json
import os
import signal
import subprocess
import sys

import pytest

from processes.runtime import shm
from processes.network.client.client import Client, Rejected
from processes.network.wire import GoodbyeReason, Kind, RejectReason, Slot
from tests.helpers.commands import ROOT, await_gone, descendants, pingpong
from tests.helpers.gateway import until_goodbye
from tests.waits import DEADLINE_S, Deadline, line, rest


def test_ctrl_c_on_the_server_says_goodbye_and_leaves_nothing_behind(served, zctx):
    server = pingpong("serve", "--players", "1", "--ticks", "600000", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    client = Client(hello["listening"], "player", "ann", zctx=zctx)
    try:
        welcome = client.join(DEADLINE_S)
        assert welcome["slot"] == Slot.A
        snapshots = 0
        deadline = Deadline()
        while not deadline.expired():  # the match has started: snapshots arrive
            client.heartbeat_if_due()
            message = client.recv(100)
            snapshots += message is not None and message.kind == Kind.SNAPSHOT
            if snapshots >= 5:
                break
        assert snapshots >= 5
        workers = descendants(server.pid)
        assert len(workers) >= 3  # forkserver, physics, AI, gateway (and the resource tracker)
        os.kill(server.pid, signal.SIGINT)
        goodbye, _ = until_goodbye(client)
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.SHUTDOWN
    finally:
        client.close()
    assert server.wait(DEADLINE_S) == 130
    interrupted = json.loads(rest(server, "the server's counters").strip().splitlines()[-1])  # the counters, also on Ctrl-C
    assert interrupted["interrupted"] and interrupted["gateway"]["players_joined"] == 1
    assert interrupted["gateway"]["goodbyes_at_end"] == 1 and interrupted["gateway"]["end"] == "shutdown"
    assert await_gone(workers) == []
    assert not shm.leftover_segments(hello["run_id"])


@pytest.mark.parametrize("signum, code, group", [(signal.SIGINT, 130, False), (signal.SIGTERM, 143, False),
                                                 (signal.SIGTERM, 143, True)])
def test_serve_in_the_background_stops_cleanly_on_sigint_and_sigterm(served, zctx, signum, code, group):
    # Started as a shell starts a background job (SIGINT ignored): either signal stops it, every
    # client is told goodbye shutdown, the summary is printed, nothing is left behind. A SIGTERM
    # to the whole process group (systemd's stop, `kill -- -PGID`) reaches every worker and the
    # forkserver too: they leave the stop to the supervisor, which stops them in order.
    server = subprocess.Popen([sys.executable, "-m", "processes.cli", "serve", "--players", "0", "--ticks", "600000",
                               "--json"], cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, start_new_session=True,
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    watcher = Client(hello["listening"], "spectator", "sp", zctx=zctx)
    try:
        watcher.join(DEADLINE_S)
        workers = descendants(server.pid)
        if group:
            os.killpg(server.pid, signum)  # started in a session (a group) of its own
        else:
            os.kill(server.pid, signum)
        goodbye, _ = until_goodbye(watcher)
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.SHUTDOWN
    finally:
        watcher.close()
    assert server.wait(DEADLINE_S) == code
    summary = json.loads(rest(server, "the server's summary").strip().splitlines()[-1])
    assert summary["interrupted"] and summary["signal"] == signal.Signals(signum).name
    assert summary["gateway"]["goodbyes_at_end"] == 1 and summary["gateway"]["end"] == "shutdown"
    assert "Traceback" not in server.stderr.read()
    assert await_gone(workers) == []
    assert not shm.leftover_segments(hello["run_id"])


def test_signals_again_and_again_while_it_stops_lose_nothing(served, zctx):
    # A second Ctrl-C or kill while the workers are being stopped used to cut the stop short:
    # BufferError tracebacks, segments left for the resource tracker, the counters lost. Here
    # SIGTERM and SIGINT come one after another until the server has exited.
    server = pingpong("serve", "--players", "0", "--ticks", "600000", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    watcher = Client(hello["listening"], "spectator", "sp", zctx=zctx)
    barrage = [signal.SIGTERM, signal.SIGINT]
    sent = 0
    try:
        watcher.join(DEADLINE_S)
        workers = descendants(server.pid)
        goodbye, deadline = None, Deadline()
        while goodbye is None and server.poll() is None and not deadline.expired():
            os.kill(server.pid, barrage[sent % 2])
            sent += 1
            watcher.heartbeat_if_due()
            message = watcher.recv(5)
            if message is not None and message.kind == Kind.GOODBYE:
                goodbye = message
        while server.poll() is None and not deadline.expired():  # and on, until it is gone
            os.kill(server.pid, barrage[sent % 2])
            sent += 1
            try:
                server.wait(0.005)
            except subprocess.TimeoutExpired:
                pass
    finally:
        watcher.close()
    code = server.wait(DEADLINE_S)
    summary = json.loads(rest(server, "the server's summary").strip().splitlines()[-1])
    errors = server.stderr.read()
    assert sent >= 2 and goodbye is not None and goodbye["reason"] == GoodbyeReason.SHUTDOWN
    assert (summary["signal"], code) in (("SIGTERM", 143), ("SIGINT", 130))  # the first one taken
    assert summary["gateway"]["goodbyes_at_end"] == 1 and summary["gateway"]["end"] == "shutdown"
    assert "Traceback" not in errors and "leaked" not in errors, errors
    assert await_gone(workers) == []
    assert not shm.leftover_segments(hello["run_id"])


def test_a_killed_gateway_is_restarted_on_the_same_endpoint_and_the_token_reclaims_the_seat(served, zctx):
    server = pingpong("serve", "--players", "1", "--ticks", "6000", "--crash-gateway-at-tick", "500", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    player = Client(hello["listening"], "player", "ann", zctx=zctx)
    thief = Client(hello["listening"], "player", "eve", Slot.A, zctx=zctx)
    try:
        first = player.join(DEADLINE_S)
        assert first["slot"] == Slot.A
        # Snapshots until the gateway dies at tick 500; the restarted one on the same endpoint
        # has no session for our heartbeats and says goodbye unknown_session, on which the
        # client says hello again with its token (Client.recv, as the document tells a client):
        # its welcome ends the wait.
        ticks, welcome, deadline = [], None, Deadline()
        while not deadline.expired():
            player.heartbeat_if_due()
            message = player.recv(100)
            if message is not None and message.kind == Kind.SNAPSHOT:
                ticks.append(message.tick)
            elif message is not None and message.kind == Kind.WELCOME:
                welcome = message
                break
        assert ticks and max(ticks) < 6000 and player.rejoins == 1
        # the seat table outlived the gateway: the token is still good and gives the same seat
        assert welcome is not None and welcome.tick > 500
        assert welcome["slot"] == Slot.A and welcome["token"] == first["token"] and welcome["name_a"] == "ann"
        with pytest.raises(Rejected) as refused:  # and nobody else may take it
            thief.join(DEADLINE_S)
        assert refused.value.reason == RejectReason.FULL
        goodbye, _ = until_goodbye(player)
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.MATCH_OVER
    finally:
        player.close()
        thief.close()
    summary = json.loads(line(server, "the server's summary"))
    assert server.wait(DEADLINE_S) == 0
    assert summary["workers"]["gateway"]["restarts"] == 1 and summary["ticks"] == 6000
    assert summary["gateway"]["seats_restored"] == 1 and summary["gateway"]["rejoined"] == 1
    assert not shm.leftover_segments(hello["run_id"])


@pytest.mark.parametrize("budget", [3, 0])
def test_a_worker_that_raises_is_restarted_and_past_the_budget_clients_are_told_server_error(served, zctx, budget):
    # The physics raises at tick 300 (the match starts when the player is seated, so it is there):
    # within the budget it is restarted and the match goes on to its end; past it, the run ends
    # and the player is told why: server_error, not shutdown.
    server = pingpong("serve", "--players", "1", "--ticks", "1500", "--fault", "physics:raise:300",
                       "--restart-budget", str(budget), "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    player = Client(hello["listening"], "player", "ann", zctx=zctx)
    try:
        assert player.join(DEADLINE_S)["slot"] == Slot.A
        goodbye, ticks = until_goodbye(player)
    finally:
        player.close()
    assert goodbye is not None, f"no goodbye; last snapshot ticks {ticks[-5:]}"
    if budget:
        assert goodbye["reason"] == GoodbyeReason.MATCH_OVER and max(ticks) == 1500
        summary = json.loads(line(server, "the server's summary"))
        assert server.wait(DEADLINE_S) == 0
        assert summary["workers"]["physics"]["raised"] == 1 and summary["workers"]["physics"]["restarts"] == 1
    else:
        assert goodbye["reason"] == GoodbyeReason.SERVER_ERROR and max(ticks) <= 300
        failed = json.loads(line(server, "the server's failure line"))
        assert server.wait(DEADLINE_S) == 1
        assert "physics worker raised InjectedFault" in failed["failed"] and "restart budget" in failed["failed"]
        assert "Traceback" in server.stderr.read()  # logged with its traceback
    assert not shm.leftover_segments(hello["run_id"])
