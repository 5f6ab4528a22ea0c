"""bench/relay.py at a tiny size: a served match, a few feed subscribers direct and through a
`pingpong relay`, one second a window; the report's structure, and every subscriber fed (no
timing asserts: the CPU shares are the benchmark's to report)."""
import json
import subprocess
import sys
from pathlib import Path

from bench import relay
from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[2]


def test_bench_relay_tiny_run_feeds_every_subscriber(capsys):
    done = subprocess.run([sys.executable, "-m", "bench.relay", "--subscribers", "3", "--hz", "60", "--seconds", "1",
                           "--rounds", "1", "--json"], capture_output=True, text=True, timeout=DEADLINE_S,
                          stdin=subprocess.DEVNULL, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert (report["subscribers"], report["snapshot_hz"], report["rounds"]) == (3, 60, 1)
    assert set(report["arms"]) == set(relay.ARMS) and len(report["per_round"]) == 1
    arms = report["per_round"][0]
    for arm in relay.ARMS:
        assert arms[arm]["gateway_cpu_pct"] is not None and arms[arm]["window_s"] > 0
    assert arms["relay"]["relay_cpu_pct"] is not None and arms["direct"]["relay_cpu_pct"] is None
    assert arms["none"]["received_median"] == 0  # no subscriber in that arm
    for arm in ("direct", "relay"):
        assert arms[arm]["received_min"] > 0 and arms[arm]["every_subscriber_received"], arms[arm]
    assert report["every_subscriber_received"]

    relay.print_summary(report)
    text = capsys.readouterr().out
    assert "through one relay" in text and "the relay itself" in text
