"""What a relay saves the gateway: its CPU with N feed subscribers connected directly, against the
same N through one `pingpong relay`, and the relay's own CPU, same served match, same run.

A served match (the stress tool's server, processes.stress.server: `pingpong serve --players 0`,
the AI on both bats, realtime, the rigid net) publishes its snapshots on the gateway's feed at
--hz. This process holds N ZeroMQ SUB sockets, the subscribers, read in bulk every
DRAIN_PERIOD_S as the stress swarm reads its feeds. Each round measures three arms for --seconds
each, in an order reversed every other round (ABC CBA) so that a drift of the machine's load
weighs on every arm alike:
- none: no subscriber (the gateway's own work: ticks read, snapshots encoded, published to nobody);
- direct: the N subscribers on the gateway's feed;
- relay: a `pingpong relay` process (processes.network.server.relay: libzmq's XSUB/XPUB proxy) is the
  feed's one subscriber and the N subscribers are its.
An arm's window opens once every subscriber has received a message (the subscriptions are live)
and closes --seconds later; the CPU of the gateway worker, of the relay and of this process (the
subscribers) over the window is user + system time from /proc (processes.stress.probes.CpuMeter),
as % of one core. The subscribers count what they received and the gaps in the feed's sequence
numbers (messages dropped at a high-water mark).

`python -m bench.relay --subscribers 200 --hz 120 --seconds 10 --rounds 2 [--json]` prints a
summary, or one JSON object with --json.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time

import zmq

from processes.stress.harness import Child, Run, StressError
from processes.stress.probes import CpuMeter, loadavg
from processes.stress.server import Server
from processes.stress.swarm.tally import HEADER, Sequence

ARMS = ("none", "direct", "relay")
DRAIN_PERIOD_S = 0.02  # the subscribers' sockets are read this often, a few messages a visit
SUBSCRIBE_TIMEOUT_S = 60.0  # every subscriber has its first message within this, or the run fails
RELAY_START_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 30.0
RCVHWM = 256  # messages queued per subscriber, as the network client's feed socket


class Subscribers:
    """N SUB sockets on the feed at `endpoint`, on a ZeroMQ context of their own (closed by close())."""

    def __init__(self, endpoint: str, n: int):
        self.zctx = zmq.Context()
        self.zctx.set(zmq.MAX_SOCKETS, max(1023, n + 64))
        self.sockets = []
        for _ in range(n):
            sock = self.zctx.socket(zmq.SUB)
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.RCVHWM, RCVHWM)
            sock.setsockopt(zmq.SUBSCRIBE, b"")
            sock.connect(endpoint)
            self.sockets.append(sock)
        self.received = [0] * n
        self.gaps = [Sequence() for _ in range(n)]

    def _drain(self) -> None:
        for i, sock in enumerate(self.sockets):
            while True:
                try:
                    data = sock.recv(zmq.NOBLOCK)
                except zmq.Again:
                    break
                self.received[i] += 1
                if len(data) >= HEADER.size:
                    self.gaps[i].see(HEADER.unpack_from(data)[4])

    def wait_subscribed(self, timeout_s: float = SUBSCRIBE_TIMEOUT_S) -> None:
        """Read until every subscriber has received a message (its subscription reached the
        publisher); StressError after timeout_s."""
        deadline = time.monotonic() + timeout_s
        while min(self.received) == 0:
            if time.monotonic() > deadline:
                silent = sum(1 for n in self.received if n == 0)
                raise StressError(f"{silent} of {len(self.sockets)} subscribers received nothing in {timeout_s:.0f} s")
            time.sleep(DRAIN_PERIOD_S)  # a reading cadence, not a synchronisation: the loop ends on what was read
            self._drain()

    def read_for(self, seconds: float) -> dict:
        """Read for `seconds`; what each subscriber received in that window, and the gaps."""
        received0 = list(self.received)
        missed0 = [g.missed for g in self.gaps]
        started = time.monotonic()
        end = started + seconds
        while time.monotonic() < end:
            time.sleep(DRAIN_PERIOD_S)  # a reading cadence (bounded by `end`)
            self._drain()
        window = time.monotonic() - started
        counts = [n - n0 for n, n0 in zip(self.received, received0)]
        missed = [g.missed - m0 for g, m0 in zip(self.gaps, missed0)]
        return {"window_s": window, "received": counts, "missed": missed}

    def close(self) -> None:
        for sock in self.sockets:
            sock.close(linger=0)
        self.zctx.term()


def _relay(run: Run, feed: str) -> tuple[Child, str]:
    """A `pingpong relay` process on the feed, and the endpoint its subscribers connect to."""
    relay = run.add(Child(["-m", "processes.cli", "relay", feed, "--bind", "tcp://127.0.0.1:0", "--json",
                           "--seconds", "86400"], "relay"))
    return relay, relay.expect(lambda o: "listening" in o, RELAY_START_TIMEOUT_S, "listening line")["listening"]


def _arm(arm: str, run: Run, server: Server, n: int, seconds: float) -> dict:
    """One arm's window: the CPU of the gateway, the relay (arm relay) and the subscribers, and
    what the subscribers received."""
    relay, endpoint = (_relay(run, server.feed) if arm == "relay" else (None, server.feed))
    subscribers = Subscribers(endpoint, 0 if arm == "none" else n)
    try:
        if arm != "none":
            subscribers.wait_subscribed()
        gateway = server.state()["pids"]["gateway"]
        pids = {"gateway": gateway, "subscribers": os.getpid(), **({"relay": relay.pid} if relay else {})}
        meter = CpuMeter(threads=("gateway",))
        meter.start(pids)
        got = subscribers.read_for(seconds)
        cpu = meter.stop()
    finally:
        subscribers.close()
        if relay is not None:
            relay.close()  # killed: a proxy holds nothing but its sockets
    if cpu.get("gateway") is None or server.state()["pids"]["gateway"] != gateway:
        raise StressError("the gateway exited or restarted during the window: its CPU time went with it")
    window = got["window_s"]
    received = got["received"]
    return {
        "gateway_cpu_pct": cpu["gateway"],
        "gateway_threads_cpu_pct": {k.split("[", 1)[1][:-1]: v for k, v in cpu.items() if k.startswith("gateway[")},
        "relay_cpu_pct": cpu.get("relay"),
        "subscribers_cpu_pct": cpu["subscribers"],
        "window_s": round(window, 2),
        "received_min": min(received, default=0),
        "received_median": statistics.median(received) if received else 0,
        "rate_hz_median": round(statistics.median(received) / window, 1) if received else None,
        "missed": sum(got["missed"]),
        "every_subscriber_received": all(k > 0 for k in received),
    }


def _spread(values: list[float | None]) -> dict | None:
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"median": round(statistics.median(values), 2), "min": min(values), "max": max(values)}


def measure(subscribers: int = 200, hz: int = 120, seconds: float = 10.0, rounds: int = 2) -> dict:
    """Every arm of every round (module docstring) against one served match; the medians and
    spreads over the rounds, and each round's arms."""
    if subscribers < 1 or hz < 1 or seconds <= 0 or rounds < 1:
        raise ValueError("--subscribers, --hz and --rounds must be >= 1 and --seconds > 0")
    load_before = loadavg()
    # the match outlasts every window and the relays' and subscriptions' start-ups
    match_s = rounds * len(ARMS) * (seconds + SUBSCRIBE_TIMEOUT_S + RELAY_START_TIMEOUT_S) + 120.0
    with tempfile.TemporaryDirectory(prefix="pingpong-bench-relay-") as tmp:
        run = Run(tmp, [])
        try:
            server = run.add(Server(tmp, players=0, snapshot_hz=hz, seconds=match_s))
            per_round = []
            for r in range(rounds):
                order = ARMS if r % 2 == 0 else ARMS[::-1]
                per_round.append({arm: _arm(arm, run, server, subscribers, seconds) for arm in order})
            server.stop(STOP_TIMEOUT_S)
        finally:
            left = run.close()
    if left:
        raise StressError(f"segments of a killed server removed: {left}")
    arms = {arm: {key: _spread([rnd[arm][key] for rnd in per_round])
                  for key in ("gateway_cpu_pct", "relay_cpu_pct", "subscribers_cpu_pct", "rate_hz_median")}
            for arm in ARMS}
    return {
        "subscribers": subscribers, "snapshot_hz": hz, "seconds": seconds, "rounds": rounds,
        "arms": arms,
        "per_round": per_round,
        "every_subscriber_received": all(rnd[arm]["every_subscriber_received"] for rnd in per_round
                                         for arm in ("direct", "relay")),
        "load_average_before_after": [load_before, loadavg()],
    }


def _text(spread: dict | None, unit: str = " %") -> str:
    if spread is None:
        return "-"
    return f"{spread['median']:.1f}{unit} [{spread['min']:.1f} .. {spread['max']:.1f}]"


def print_summary(report: dict) -> None:
    arms = report["arms"]
    before, after = report["load_average_before_after"]
    print(f"relay fan-out: {report['subscribers']} subscribers at {report['snapshot_hz']} Hz, {report['seconds']:g} s "
          f"windows, median [min .. max] of {report['rounds']} round(s), % of one core "
          f"(load average {before[0]:.2f} before, {after[0]:.2f} after)")
    print(f"  gateway, no subscribers:        {_text(arms['none']['gateway_cpu_pct'])}")
    print(f"  gateway, subscribers direct:    {_text(arms['direct']['gateway_cpu_pct'])}")
    print(f"  gateway, through one relay:     {_text(arms['relay']['gateway_cpu_pct'])}")
    print(f"  the relay itself:               {_text(arms['relay']['relay_cpu_pct'])}")
    print(f"  the subscribers (this process): direct {_text(arms['direct']['subscribers_cpu_pct'])}, "
          f"relay {_text(arms['relay']['subscribers_cpu_pct'])}")
    for arm in ("direct", "relay"):
        rounds = report["per_round"]
        print(f"  {arm}: messages per subscriber and second, median {_text(arms[arm]['rate_hz_median'], '')}; "
              f"fewest received by one subscriber in a window {min(r[arm]['received_min'] for r in rounds)}; "
              f"missed (feed gaps) {sum(r[arm]['missed'] for r in rounds)}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--subscribers", type=int, default=200, help="feed subscribers, direct or on the relay")
    parser.add_argument("--hz", type=int, default=120, help="the gateway's snapshots per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each arm's window")
    parser.add_argument("--rounds", type=int, default=2, help="rounds of the three arms")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    try:
        report = measure(args.subscribers, args.hz, args.seconds, args.rounds)
    except (ValueError, StressError) as err:
        parser.exit(2, f"bench.relay: {err}\n")
    if args.json:
        print(json.dumps(report))
    else:
        print_summary(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
