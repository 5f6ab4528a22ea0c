"""The abuse task: one hostile peer's attack on a served match, for `pingpong stress --scenario abuse`.

Each attack speaks ZMTP and the wire correctly but behaves badly (SPEC "attack"):
- flood: a player that sends valid inputs as fast as its socket takes them;
- multipart: raw ZMTP peers (swarm.zmtp.RawPeer), each opening a message of 4000-byte frames
  that never ends, 100 MB each unless the gateway cuts them first;
- oversized: raw peers that announce a frame far beyond the gateway's frame bound, and
  DEALERs that send one;
- hellos: HELLO_SOCKETS sockets that say hello as spectators and never answer the welcome,
  then hello again on the same sockets every second (hoarding the places); in the middle of it
  an honest spectator (a Client that answers its welcome) asks for a place: the probe;
- slow: feed subscribers (raw ZMTP SUB peers) that subscribe and never read.
It prints {"event": "started", "t"} when the attack begins (CLOCK_MONOTONIC, the harness's
clock too) and its report at the end, with "t_end": the attack's window for the honest
spectators' rates.
"""
from __future__ import annotations

import struct
import threading
import time
from collections import Counter
from urllib.parse import urlparse

import zmq

from processes.network import wire
from processes.network.client.client import Client, Rejected
from processes.network.wire import MAX_FRAME_BYTES, NO_TOKEN, InputMode, Kind, Role, Slot
from processes.stress.swarm import context, emit
from processes.stress.swarm.zmtp import FRAME_LONG, RawPeer

MULTIPART_PEERS = 4  # at once, as the four peers that grew an unguarded gateway to 2.5 GB
MULTIPART_BYTES = 100 * 1024 * 1024  # each, in frames within the frame bound
MULTIPART_FRAME = 4000
HELLO_SOCKETS = 500
HELLO_AGAIN_S = 1.0
SLOW_SUBSCRIBERS = 32
CUT_WAIT_S = 5.0  # a peer not cut within this after its attack is counted as not cut
JOIN_S = 30.0


def _host_port(address: str) -> tuple[str, int]:
    url = urlparse(address)
    return url.hostname, url.port


def flood(spec: dict) -> dict:
    """Valid inputs of seat `slot` as fast as the socket takes them, for `seconds`."""
    zctx = context(4)
    client = Client(spec["address"], "player", "flood", zctx=zctx)
    try:
        client.join(JOIN_S)
        data = bytearray(wire.encode(Kind.INPUT, seq=1, tick=1, slot=client.slot, mode=InputMode.FORCE,
                                     force=(1.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0), target_pos=(0.0, 0.0, 0.0),
                                     target_quat=(0.0, 0.0, 0.0, 0.0)))
        seq, sent, blocked = client.seq, 0, 0
        start = _started()
        end = start + spec["seconds"]
        while time.monotonic() < end:
            for _ in range(64):
                seq += 1
                struct.pack_into("<Q", data, 8, seq)
                try:
                    client.sock.send(data, flags=zmq.NOBLOCK)
                    sent += 1
                except zmq.Again:  # its high-water mark: the gateway reads no faster
                    blocked += 1
                    client.sock.poll(1, zmq.POLLOUT)
                    break
            while client.recv(0) is not None:  # its snapshots and heartbeats, not to pile up
                pass
        t_end = time.monotonic()
        client.seq = seq
        client.leave()
        return {"sent": sent, "blocked": blocked, "seconds": round(t_end - start, 3), "t_end": t_end,
                "inputs_per_s": round(sent / max(t_end - start, 1e-9)), "goodbye": _goodbye(client)}
    finally:
        client.close()
        zctx.term()


def multipart(spec: dict) -> dict:
    """MULTIPART_PEERS raw peers at once, each an unfinished message of MULTIPART_BYTES."""
    host, port = _host_port(spec["address"])
    peers = [RawPeer(host, port) for _ in range(MULTIPART_PEERS)]
    sent = [0] * len(peers)
    cut = [False] * len(peers)
    start = _started()

    def attack(i: int) -> None:
        sent[i] = peers[i].open_message(MULTIPART_BYTES // MULTIPART_FRAME, MULTIPART_FRAME, spec["seconds"])
        cut[i] = peers[i].closed_by_server(CUT_WAIT_S)

    threads = [threading.Thread(target=attack, args=(i,), daemon=True) for i in range(len(peers))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(spec["seconds"] + CUT_WAIT_S + 10.0)
    t_end = time.monotonic()
    for peer in peers:
        peer.close()
    return {"peers": len(peers), "cut": sum(cut), "sent_mb": [round(s / 2**20, 2) for s in sent],
            "seconds": round(t_end - start, 3), "t_end": t_end}


def oversized(spec: dict) -> dict:
    """For `seconds`: a raw peer announcing a 1 GiB frame and sending its first MB, then a
    DEALER sending a frame of 4 x MAX_FRAME_BYTES; each must lose its connection."""
    host, port = _host_port(spec["address"])
    zctx = context(4)
    counts: Counter[str] = Counter()
    start = _started()
    end = start + spec["seconds"]
    while time.monotonic() < end:
        peer = RawPeer(host, port)
        try:
            peer.sock.sendall(bytes([FRAME_LONG]) + struct.pack(">Q", 1 << 30) + bytes(1 << 20))
        except OSError:
            pass  # cut while sending: what it is for
        counts["announced_1gib"] += 1
        counts["announced_cut"] += peer.closed_by_server(CUT_WAIT_S)
        peer.close()
        dealer = zctx.socket(zmq.DEALER)
        dealer.setsockopt(zmq.LINGER, 0)
        monitor = dealer.get_monitor_socket(zmq.EVENT_DISCONNECTED)
        dealer.connect(spec["address"])
        dealer.send(bytes(4 * MAX_FRAME_BYTES))
        counts["big_frames"] += 1
        counts["big_frame_cut"] += bool(monitor.poll(int(CUT_WAIT_S * 1000)))
        dealer.disable_monitor()
        monitor.close()
        dealer.close()
    t_end = time.monotonic()
    zctx.term()
    return {**counts, "seconds": round(t_end - start, 3), "t_end": t_end}


def hellos(spec: dict) -> dict:
    """HELLO_SOCKETS bare hellos in about half a second, hello again every HELLO_AGAIN_S on the
    same sockets; after `probe_after_s` an honest spectator asks for a place (the probe)."""
    zctx = context(HELLO_SOCKETS + 8)
    hello = wire.encode(Kind.HELLO, role=Role.SPECTATOR, slot=Slot.NONE, name="hoard", token=NO_TOKEN)
    sockets = []
    answers: Counter[str] = Counter()
    probe: dict = {}
    start = _started()
    try:
        for _ in range(HELLO_SOCKETS):
            sock = zctx.socket(zmq.DEALER)
            sock.setsockopt(zmq.LINGER, 0)
            sock.connect(spec["address"])
            sock.send(hello, flags=zmq.NOBLOCK)
            sockets.append(sock)
        poller = zmq.Poller()
        for sock in sockets:
            poller.register(sock, zmq.POLLIN)
        next_again = time.monotonic() + HELLO_AGAIN_S
        probe_at = start + spec["probe_after_s"]
        end = start + spec["seconds"]
        while time.monotonic() < end:
            for sock, _ in poller.poll(10):  # read (never answer): welcomes, rejects, goodbyes
                while True:
                    try:
                        message = wire.decode(sock.recv(flags=zmq.NOBLOCK))
                    except zmq.Again:
                        break
                    except wire.WireError:
                        answers["undecodable"] += 1
                        break
                    answers[message.kind.name.lower()] += 1
            if time.monotonic() >= next_again:
                next_again += HELLO_AGAIN_S
                for sock in sockets:
                    try:
                        sock.send(hello, flags=zmq.NOBLOCK)
                    except zmq.Again:
                        answers["hello_again_blocked"] += 1
            if not probe and time.monotonic() >= probe_at:
                probe = _probe(spec["address"], zctx)
        t_end = time.monotonic()
    finally:
        for sock in sockets:
            sock.close()
        zctx.term()
    return {"sockets": len(sockets), "answers": dict(answers), "probe": probe,
            "seconds": round(t_end - start, 3), "t_end": t_end}


def _probe(address: str, zctx) -> dict:
    """An honest spectator's join among the hoarder's hellos: told `full` with a hint, it asks
    again when the hint says (a bare hello holds its place a heartbeat period before a newcomer
    may take it), as a client should (docs/protocol.md), within JOIN_S in all."""
    asked = time.monotonic()
    deadline = asked + JOIN_S
    rejects = 0
    while True:
        client = Client(address, "spectator", "probe", zctx=zctx)
        try:
            client.join(max(0.1, deadline - time.monotonic()))
            return {"answer": "welcome", "join_s": round(time.monotonic() - asked, 3), "rejects": rejects}
        except Rejected as rejected:
            rejects += 1
            retry = rejected.retry_s
            if retry is None or time.monotonic() + retry >= deadline:
                return {"answer": "reject", "detail": str(rejected), "rejects": rejects}
        except TimeoutError:
            return {"answer": "none", "rejects": rejects}
        finally:
            client.leave()
            client.close()
        time.sleep(retry)  # the server's hint: when a place may be free


def slow(spec: dict) -> dict:
    """SLOW_SUBSCRIBERS raw SUB peers on the feed that subscribe to everything, never read."""
    host, port = _host_port(spec["feed"])
    peers = []
    start = _started()
    for _ in range(SLOW_SUBSCRIBERS):
        peer = RawPeer(host, port, socket_type=b"SUB")
        peer.send(b"\x01")  # subscribe to every message (ZMTP 3.0's subscription message)
        peers.append(peer)
    time.sleep(max(0.0, start + spec["seconds"] - time.monotonic()))  # the attack: holding on, reading nothing
    t_end = time.monotonic()
    for peer in peers:
        peer.close()
    return {"subscribers": len(peers), "seconds": round(t_end - start, 3), "t_end": t_end}


def _started() -> float:
    t = time.monotonic()
    emit({"event": "started", "t": t})
    return t


def _goodbye(client: Client) -> str | None:
    return client.goodbye.name.lower() if client.goodbye is not None else None


ATTACKS = {"flood": flood, "multipart": multipart, "oversized": oversized, "hellos": hellos, "slow": slow}


def abuse(spec: dict) -> dict:
    """Run the attack SPEC "attack" names; its report."""
    return {"attack": spec["attack"], **ATTACKS[spec["attack"]](spec)}
