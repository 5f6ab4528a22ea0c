"""The suite's waits (tests/waits.py): one deadline, an alarm above it, failures that say what was awaited."""
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from tests import waits

ROOT = Path(__file__).resolve().parents[1]


def test_the_per_test_alarm_is_the_deadline_times_alarm_deadlines():
    ini = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert float(ini["timeout"]) == waits.ALARM_DEADLINES * waits.DEADLINE_S
    assert waits.DEADLINE_S >= 120.0  # minutes: a safety net, not a guess at the machine's speed


def test_no_test_sets_an_alarm_of_its_own():
    marked = [str(path.relative_to(ROOT)) for path in (ROOT / "tests").rglob("*.py")
              if re.search(r"mark\.timeout\(", path.read_text()) and path.name != "test_waits.py"]
    assert marked == []


def test_line_returns_each_line_even_when_they_came_together():
    """Two lines written at once: the second is there at once, not after the deadline (select()
    on the pipe alone sees nothing once the first readline() buffered both)."""
    proc = subprocess.Popen([sys.executable, "-c", "print('one'); print('two', flush=True); input()"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert waits.line(proc, "the first line") == "one\n"
        assert waits.line(proc, "the second line", seconds=waits.DEADLINE_S) == "two\n"
        proc.stdin.write("\n")
        proc.stdin.flush()
        assert waits.exited(proc, "the end") == 0
        assert waits.rest(proc, "the rest") == ""
    finally:
        proc.kill()
        proc.wait()
        for pipe in (proc.stdin, proc.stdout, proc.stderr):
            pipe.close()


def test_a_wait_that_fails_says_what_it_awaited_and_what_it_saw():
    proc = subprocess.Popen([sys.executable, "-c", "import sys; sys.stderr.write('boom'); sys.exit(3)"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with pytest.raises(AssertionError, match=r"the listening line: the process closed its output first.*boom"):
            proc.wait()
            waits.line(proc, "the listening line")
    finally:
        proc.stdout.close()
        proc.stderr.close()
    seen = iter(range(1000))
    with pytest.raises(AssertionError, match=r"the counter at 5: not within 0 s; saw 1"):
        waits.wait_for(lambda: False, "the counter at 5", seen=lambda: next(seen) + 1, seconds=0.0)
    assert waits.wait_for(lambda: 7, "a value") == 7
