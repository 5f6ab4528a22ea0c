"""Every `pingpong` subcommand of this stage, smoke-run as a subprocess (with --ticks 2 where it runs a scene)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from engine.physics.scene import SCENES_DIR
from tests.waits import DEADLINE_S

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def pingpong(*args):
    return subprocess.run([sys.executable, "-m", "processes", *args], capture_output=True, text=True,
                          timeout=DEADLINE_S, stdin=subprocess.DEVNULL)


@pytest.mark.parametrize("scene", ["drop", "serve", "rally"])
def test_run_json_two_ticks(scene):
    done = pingpong("run", scene, "--ticks", "2", "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["scene"] == scene and summary["ticks"] == 2
    assert summary["sim_seconds"] == pytest.approx(0.002)


def test_run_drop_reports_bounce_heights():
    done = pingpong("run", str(SCENES_DIR / "drop.toml"), "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["bounce_heights_m"][0] == pytest.approx(0.23, abs=0.01)  # ITTF rule 2.1.3
    assert all(e["body"] == "table" for e in summary["events"])


def test_run_human_summary_and_overrides():
    done = pingpong("run", "serve", "--integrator", "rk4", "--dt", "0.0005")
    assert done.returncode == 0, done.stderr
    assert "integrator rk4" in done.stdout and "table" in done.stdout


def test_match_two_ticks():
    done = pingpong("match", "--ticks", "2", "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["scene"] == "match" and summary["ticks"] == 2 and summary["winner"] is None
    assert set(summary["workers"]) == {"physics", "net", "ai"}  # the default match plays the cloth net


def test_match_of_the_example_bots_two_ticks():
    done = pingpong("match", "--scene", "match_rigid", "--a", str(EXAMPLES / "block.py") + ":Block", "--b",
                    str(EXAMPLES / "attack.py") + ":Attack", "--ticks", "2", "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["ticks"] == 2 and summary["bot_errors"] == [] and summary["stopped"] is None


@pytest.mark.parametrize("player, message", [("no/such.py:Bot", "no file no/such.py"),
                                             ("grandmaster", "a bot (FILE.py:Class or module:Class)")])
def test_match_with_a_bad_player_exits_2_with_the_reason(player, message):
    done = pingpong("match", "--a", player, "--ticks", "2")
    assert done.returncode == 2 and message in done.stderr, done.stderr


def test_serve_plays_a_bot_in_an_ai_seat_two_ticks():
    done = pingpong("serve", "--scene", "match_rigid", "--players", "0", "--a", str(EXAMPLES / "block.py") + ":Block",
                    "--ticks", "2", "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.splitlines()[-1])
    assert summary["ticks"] == 2 and summary["bot_errors"] == [] and "ai" in summary["workers"]


def test_serve_refuses_a_bot_for_a_remote_seat():
    done = pingpong("serve", "--players", "1", "--a", str(EXAMPLES / "block.py") + ":Block", "--ticks", "2")
    assert done.returncode == 2 and "--a: bat A is played remotely with --players 1" in done.stderr, done.stderr


def test_replay_two_ticks(tmp_path):
    path = tmp_path / "short.replay"
    done = pingpong("match", "--ticks", "40", "--replay", str(path), "--json")
    assert done.returncode == 0, done.stderr
    done = pingpong("replay", str(path), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["frames"] == 5  # ticks 0, 10, 20, 30, 40


def test_replay_html_is_one_page_with_the_wire_messages_of_the_frames(tmp_path):
    import base64
    import re

    from processes.network import wire

    path, page = tmp_path / "short.replay", tmp_path / "short.html"
    assert pingpong("match", "--ticks", "200", "--replay", str(path), "--json").returncode == 0
    done = pingpong("replay", str(path), "--html", str(page), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["html"] == str(page)
    text = page.read_text()
    messages = json.loads(re.search(r'<script type="application/json" id="messages">(.*?)</script>', text).group(1))
    decoded = [wire.decode(base64.b64decode(m)) for m in messages]
    assert decoded[0].kind == wire.Kind.WELCOME and decoded[0]["dt"] > 0
    ticks = [m.tick for m in decoded if m.kind == wire.Kind.SNAPSHOT]
    assert ticks == sorted(ticks) and ticks[-1] == 200 and len(ticks) >= 20  # a frame every 10 ticks


def test_replay_of_a_file_that_is_not_one(tmp_path):
    bad = tmp_path / "bad.replay"
    bad.write_bytes(b"not a zip")
    done = pingpong("replay", str(bad))
    assert done.returncode == 2 and "not a pingpong replay" in done.stderr


def test_bad_scene_exits_2_with_the_reason(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('effects = ["gravity"]\n[ball]\npos = [0, 0, "up"]\n')
    done = pingpong("run", str(bad))
    assert done.returncode == 2
    assert f"{bad}: ball.pos[2]: must be a number" in done.stderr


def test_bad_integrator_exits_2():
    done = pingpong("run", "drop", "--integrator", "leapfrog")
    assert done.returncode == 2 and "integrator: must be one of" in done.stderr


def _bench_match(*flags: str) -> dict:
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "match", "--quick", "--json", *flags],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["same_match"] is True  # the lockstep match and the in-process one agree
    assert set(report["processes"]["workers"]) == {"physics", "net", "ai"}  # the default match: the cloth net
    assert all("cpu_s" in info for info in report["processes"]["workers"].values())
    physics = report["processes"]["workers"]["physics"]
    # The physics' hand-offs, split by whom it waited for: the net and the AI (no restarts here).
    assert physics["handoff_net_s"] + physics["handoff_ai_s"] == pytest.approx(physics["handoff_s"], rel=1e-12)
    assert 0 < physics["ai_decisions"] <= physics["ai_turns"]
    return report


def test_bench_match_quick_json(tmp_path):
    """By default the worker processes speculate (the cloth net's match allows it)."""
    picture = tmp_path / "timeline.png"
    report = _bench_match("--timeline", str(picture))
    assert report["processes"]["speculate"] is True
    physics = report["processes"]["workers"]["physics"]
    assert {"net_rollbacks", "net_ticks_again"} <= set(physics)
    # A turn at each control tick (or, where the workers outnumber the cores, at each where a
    # player could decide, the others skipped), and again at those a go-back steps again.
    ticks = round(report["sim_seconds"] / 0.001)  # the match scene's dt
    assert physics["ai_turns"] + physics["ai_skipped"] >= -(-ticks // 10)
    # The round's ratio to the in-process match, and the shares of its wall time by workers at work.
    ratio = report["over_in_process"]
    assert ratio["rounds"] == [ratio["median"]]
    assert ratio["median"] == pytest.approx(report["processes"]["realtime_factor"] / report["in_process"]["realtime_factor"])
    assert sum(report["processes"]["working"].values()) == pytest.approx(1.0)
    assert sum(report["processes"]["beside_net"].values()) == pytest.approx(1.0)  # the net's work, the rest by who
    assert report["timeline"]["path"] == str(picture) and picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bench_match_without_speculating_gives_each_control_tick_one_turn():
    report = _bench_match("--no-speculate")
    assert report["processes"]["speculate"] is False
    physics = report["processes"]["workers"]["physics"]
    ticks = round(report["sim_seconds"] / 0.001)  # the match scene's dt
    assert physics["ai_turns"] + physics["ai_skipped"] == -(-ticks // 10)


def test_bench_match_sets_the_air_damped_match_beside_the_default():
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "match", "--scene", "match,match_air",
                           "--quick", "--ticks", "3000", "--repeat", "2", "--json"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    # The first scene's report keeps every key of the one-scene report; the others go beside it.
    assert set(report) >= {"scene", "net", "best_of", "seed", "same_match", "sim_seconds", "processes", "in_process",
                           "target", "air_damping_per_s", "outcome", "beside"}
    assert [report["scene"]] + [other["scene"] for other in report["beside"]] == ["match", "match_air"]
    air = report["beside"][0]
    assert (report["air_damping_per_s"], air["air_damping_per_s"]) == (5.0, 0.2)  # NetSpec's; AIR_DAMPING_PHYSICAL
    for one in (report, air):
        assert one["same_match"] is True  # each scene's lockstep match and its in-process one agree
        assert one["sim_seconds"] == pytest.approx(3.0)  # --ticks 3000 at 1 ms
        assert one["processes"]["workers"]["net"]["awake_ticks"] == one["in_process"]["net_awake_ticks"]
        assert set(one["outcome"]) >= {"winner", "games", "points", "point_reasons"}
    assert air["realtime_factor_ratio"]["processes"] > 0.0
    # --repeat 2: every scene's matches in worker processes twice, round by round; the ratio is the rounds' median
    ratios = air["realtime_factor_ratio"]["processes_rounds"]
    assert len(ratios) == 2 and air["realtime_factor_ratio"]["processes"] == pytest.approx(sum(ratios) / 2)
    for one in (report, air):
        assert len(one["processes"]["realtime_factors"]) == 2
        assert one["processes"]["realtime_factor"] in one["processes"]["realtime_factors"]  # the median round's


def test_bench_match_refuses_no_rounds():
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "match", "--repeat", "0", "--quick"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 2 and "--repeat 0 must be >= 1" in done.stderr


def test_bench_match_refuses_a_scene_without_a_match():
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "match", "--scene", "drop", "--quick"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 2 and "has no [match] section" in done.stderr


def test_stability_json_one_case():
    done = pingpong("stability", "--case", "two impacts", "--json")
    assert done.returncode == 0, done.stderr
    row = json.loads(done.stdout.splitlines()[0])
    assert row["result"] == "stable" and row["finite"] and not row["tunnelled"]
    assert set(row) >= {"finite", "tunnelled", "max_penetration_m", "energy_gain"}


def test_replay_pictures(tmp_path):
    path = tmp_path / "short.replay"
    assert pingpong("match", "--ticks", "600", "--replay", str(path)).returncode == 0
    png, gif = tmp_path / "r.png", tmp_path / "r.gif"
    done = pingpong("replay", str(path), "--png", str(png), "--gif", str(gif))
    assert done.returncode == 0, done.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")


# The help of `pingpong` and of every command, in one fresh interpreter; it prints the roots of
# the modules it imported. `python -m processes --help` runs as runpy runs it for `-m`.
HELP_IMPORTS = """
import argparse, contextlib, io, json, runpy, sys
sys.argv = ["pingpong", "--help"]
with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
    runpy.run_module("processes", run_name="__main__", alter_sys=True)
from processes.cli import build_parser, main
commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
for command in commands:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        main([command, "--help"])
print(json.dumps({"commands": sorted(commands), "roots": sorted({name.split(".")[0] for name in sys.modules})}))
"""
# What the command functions import when they run, never the parser.
HEAVY = {"numpy", "numba", "zmq", "rich", "engine", "net_kernel", "scipy", "matplotlib"}


def test_help_imports_no_engine_numpy_numba_or_zmq():
    done = subprocess.run([sys.executable, "-c", HELP_IMPORTS], capture_output=True, text=True, timeout=DEADLINE_S,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert {"match", "serve", "relay", "stress", "tournament", "sweep"} <= set(report["commands"])
    assert not HEAVY & set(report["roots"]), sorted(HEAVY & set(report["roots"]))


def test_the_parsers_spelled_out_defaults_are_the_runs():
    from engine.physics.scene import SKILL_NAMES
    from engine.play.players import DEFAULT_BUDGET_S
    from processes.cli import common, serve, tournament
    from processes.workers import PLAYERS_TIMEOUT_S

    assert tournament.SKILL_NAMES == SKILL_NAMES
    assert serve.PLAYERS_TIMEOUT_S == PLAYERS_TIMEOUT_S
    from processes import supervisor
    assert (serve.RESTART_BUDGET, serve.RESTART_WINDOW_S) == (supervisor.RESTART_BUDGET, supervisor.RESTART_WINDOW_S)
    assert common.BOT_BUDGET_MS == DEFAULT_BUDGET_S * 1000
