"""`pingpong decode`: a captured message pretty-printed or as JSON; a bad one exits 2 with its reason."""
import json
import math
import subprocess
import sys

from tests.helpers.golden import GOLDEN, GOLDEN_HEX, patched
from tests.waits import DEADLINE_S


def _pingpong(*args):
    return subprocess.run([sys.executable, "-m", "processes", *args], capture_output=True, text=True,
                          timeout=DEADLINE_S, stdin=subprocess.DEVNULL)


def test_decode_command_hex_json():
    done = _pingpong("decode", GOLDEN_HEX["input_force"], "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["ok"] and out["kind"] == "input" and out["seq"] == 42 and out["slot"] == "a"
    assert out["force"] == [12.5, -3.0, 9.81]


def test_decode_command_file_human(tmp_path):
    path = tmp_path / "capture.bin"
    path.write_bytes(GOLDEN["snapshot"])
    done = _pingpong("decode", str(path))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("snapshot  seq 1000  tick 16667") and "phase        struck" in done.stdout


def test_decode_command_bad_message_exits_2_with_the_reason():
    done = _pingpong("decode", patched("input_force", force=(math.nan, 0, 0)).hex(), "--json")
    assert done.returncode == 2
    assert json.loads(done.stdout)["reason"] == "non_finite" and "non_finite" in done.stderr
    done = _pingpong("decode", GOLDEN_HEX["heartbeat"][:-2])
    assert done.returncode == 2 and "bad message: too_short" in done.stderr


def test_decode_command_neither_file_nor_hex_exits_2():
    done = _pingpong("decode", "no-such-capture.bin")
    assert done.returncode == 2 and "neither a file nor a hex string" in done.stderr
