"""`pingpong bench env`: what the training environments and the bot API cost, in one run.

- steps: environment steps per second of Return-v0 against novice, `hold` actions at the ready
  pose (the agent never strikes, so each episode runs to the opponent's point or its truncation),
  rigid net and cloth net: one PingPongEnv; the native vector env (engine.learning.vector_env, N tables in
  this process) at N = --tables; Gymnasium's AsyncVectorEnv of N (N processes, forkserver) at N =
  --async-tables. Every step of every table counts, autoresets included; the first steps (kernels
  loaded, in each process) are not timed. Each figure's ratio is to the one environment's of the
  same net.
- batched (Return-v1 against novice, `hold` actions at the ready pose in the agent's frame), rigid
  net and cloth net: one version-1 PingPongEnv and the native vector env at N = --batched, which
  steps its tables in one numba call (engine.learning.batch), measured in turns (the one
  environment, then each N, ROUNDS times: a drifting machine moves them alike); medians, and the
  ratios to that one environment as the median of the turns' ratios with their range. Each N's
  wall time is split into the compiled call (engine.learning.batch.TableBatch.seconds), the AI
  profiles' decisions (Python: BatAI thinking a stroke out), the cloth net's own steps (in Python:
  its NetSim over the ticks it owes, and the ticks near the ball with the ball's, the table's
  state handed over and back) and the rest (episodes' starts, the vector env's own
  work); "the compiled call alone" is the ratio the batch would reach if all else took no time.
- physics share: the share of the one environment's step (the process's CPU time, every thread)
  spent in the physics (engine.physics.world.advance, timed around each call: the numba tick kernel and,
  with the cloth net, the net's kernels): the most that stepping a batch of tables' physics in one
  numba call could take away; the rest is the referee's, the players' and the step's Python work.
- players: the same in-process match (match_rigid, seed 0) with A played by `pro` and by
  examples/block.py:Block, B by novice, each --ticks ticks: engine.play.match.Match.ai_seconds (all
  the players' decisions and control laws) per control tick, and the bot's own act() (CPU) per
  decision.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from bench.study import Study
from bench.study import run as run_study

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
READY = np.array([1.75, 0.0, 0.15, -1.0, 0.0, 0.0])  # a hold action: end B's ready pose
WARM_STEPS = 30  # untimed vector steps first: every process's kernels loaded
NETS = ("rigid", "cloth")


def _timed(step, n: int, seconds: float) -> float:
    """Steps per second of wall time of `step()` (n environment steps each), after WARM_STEPS."""
    for _ in range(WARM_STEPS):
        step()
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        step()
        steps += n
    return steps / (time.perf_counter() - started)


def single_steps_per_second(seconds: float, net: str) -> dict:
    """One environment's steps per second, and the share of it in the physics."""
    from engine.learning.env import PingPongEnv
    import engine.play.match

    env = PingPongEnv(opponent="novice", net=net)
    env.reset(seed=0)
    done = False
    while not done:  # the first episode: every kernel loaded
        _, _, terminated, truncated, _ = env.step(READY)
        done = terminated or truncated
    env.reset()

    def step():
        _, _, terminated, truncated, _ = env.step(READY)
        if terminated or truncated:
            env.reset()

    physics = engine.play.match.advance
    inside = [0.0]

    def timed_physics(*args, **kwargs):
        started = time.process_time()
        try:
            return physics(*args, **kwargs)
        finally:
            inside[0] += time.process_time() - started

    rate = _timed(step, 1, seconds)
    engine.play.match.advance = timed_physics
    try:
        started, cpu = time.perf_counter(), time.process_time()
        while time.perf_counter() - started < seconds / 2:
            step()
        share = inside[0] / (time.process_time() - cpu)
    finally:
        engine.play.match.advance = physics
    return {"steps_per_s": rate, "physics_share": share}


READY_V1 = np.array([-0.6, 0.0, 0.0, 0.0, 0.0, 0.0])  # a version-1 hold action: near the agent's ready pose


ROUNDS = 3  # the batched study's turns: one environment, then each N, again and again


def batched_steps_per_second(tables: list[int], seconds: float, rounds: int = ROUNDS, net: str = "rigid") -> dict:
    """One version-1 environment's steps per second, and the batched vector env's at each N, with
    the `net` net.

    Measured in `rounds` turns of seconds / rounds each (the one environment, then each N), so
    that a machine whose speed drifts during the study moves the figures alike: a figure is the
    median of its turns, a ratio the median of the turns' ratios, with their least and greatest.
    """
    from engine.learning.env import PingPongEnv
    from engine.learning.vector_env import PingPongVectorEnv

    env = PingPongEnv(opponent="novice", version=1, net=net)
    env.reset(seed=0)

    def step():
        _, _, terminated, truncated, _ = env.step(READY_V1)
        if terminated or truncated:
            env.reset()

    vectors = {n: PingPongVectorEnv(n, opponent="novice", version=1, net=net) for n in tables}
    try:
        for vector in vectors.values():
            vector.reset(seed=0)
        singles, turns = [], {n: [] for n in tables}
        for _ in range(rounds):
            singles.append(_timed(step, 1, seconds / rounds))
            for n, vector in vectors.items():
                turns[n].append(_batched_turn(vector, n, seconds / rounds, singles[-1]))
    finally:
        for vector in vectors.values():
            vector.close()
    out = {"single": float(np.median(singles)), "rounds": rounds, "batched": {}}
    for n, rows in turns.items():
        ratios = [row["ratio"] for row in rows]
        wall = sum(row["wall"] for row in rows)
        compiled = sum(row["compiled"] for row in rows)
        out["batched"][str(n)] = {
            "steps_per_s": float(np.median([row["steps_per_s"] for row in rows])),
            "ratio": float(np.median(ratios)), "ratio_range": [min(ratios), max(ratios)],
            "compiled_share": compiled / wall,
            "decisions_share": sum(row["decisions"] for row in rows) / wall,
            "net_share": sum(row["net"] for row in rows) / wall,
            "compiled_alone_ratio": float(np.median([row["ratio"] * row["wall"] / row["compiled"] for row in rows]))}
    return out


def _batched_turn(vector, n: int, seconds: float, single: float) -> dict:
    """One turn of the batched vector env of n tables: its steps/s, their ratio to `single`, and
    the wall, compiled, decisions and net seconds of the timed steps."""
    actions = np.stack([READY_V1] * n)
    batch = vector.batch
    spent = {}

    def timed_step():
        if not spent:  # the warm-up is over: count from here
            spent.update(batch.seconds, started=time.perf_counter())
        vector.step(actions)

    rate = _timed(timed_step, n, seconds)
    return {"steps_per_s": rate, "ratio": rate / single, "wall": time.perf_counter() - spent["started"],
            "compiled": batch.seconds["compiled"] - spent["compiled"],
            "decisions": batch.seconds["decisions"] - spent["decisions"], "net": batch.seconds["net"] - spent["net"]}


def native_steps_per_second(n: int, seconds: float, net: str) -> float:
    """engine.learning.vector_env.PingPongVectorEnv of n tables: environment steps per second."""
    from engine.learning.vector_env import PingPongVectorEnv

    vector = PingPongVectorEnv(n, opponent="novice", net=net)
    vector.reset(seed=0)
    actions = np.stack([READY] * n)
    try:
        return _timed(lambda: vector.step(actions), n, seconds)
    finally:
        vector.close()


def async_steps_per_second(n: int, seconds: float, net: str) -> float:
    """gymnasium.vector.AsyncVectorEnv of n (n processes): environment steps per second."""
    import gymnasium

    vector = gymnasium.vector.AsyncVectorEnv(
        [lambda: gymnasium.make("engine.learning.env:pingpong/Return-v0", opponent="novice", net=net)] * n,
        context="forkserver")
    try:
        vector.reset(seed=list(range(n)))
        actions = np.stack([READY] * n)
        return _timed(lambda: vector.step(actions), n, seconds)
    finally:
        vector.close()


def players_per_control_tick(ticks: int) -> dict:
    """Match.ai_seconds per control tick with A played by pro and by the Block bot (B: novice)."""
    from engine.physics.scene import load_scene
    from engine.play.match import Match, match_scene

    base = load_scene("match_rigid")
    out = {}
    for name, player in (("pro", "pro"), ("block_bot", f"{EXAMPLES / 'block.py'}:Block")):
        match = Match(match_scene(base, player, "novice", best_of=5), seed=0)
        result = match.play(max_ticks=ticks)
        control_ticks = result.ticks // match.compiled.control_period
        seat = match.ais[0]
        out[name] = {"ticks": result.ticks, "ai_us_per_control_tick": 1e6 * match.ai_seconds / control_ticks,
                     "decisions_of_a": seat.decisions,
                     "act_us_per_decision": 1e6 * seat.act_seconds / seat.decisions if not seat.profile else None}
    out["ratio_bot_to_pro"] = out["block_bot"]["ai_us_per_control_tick"] / out["pro"]["ai_us_per_control_tick"]
    return out


def _counts(text: str, flag: str) -> list[int]:
    try:
        counts = [int(x) for x in text.split(",")]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise ValueError(f"{flag} {text!r}: give table counts >= 1 as N[,N...], e.g. 1,8,64")
    return counts


def _run(args: argparse.Namespace, progress=None) -> dict:
    if args.seconds <= 0 or args.ticks < 1:
        raise ValueError(f"--seconds {args.seconds} must be > 0 and --ticks {args.ticks} >= 1")
    tables = _counts(args.tables, "--tables") if not args.quick else [1, 8]
    async_tables = _counts(args.async_tables, "--async-tables") if not args.quick else [2]
    seconds = args.seconds if not args.quick else 1.0
    with open("/proc/loadavg") as f:
        load_before = float(f.read().split()[0])
    result: dict = {"seconds": seconds, "nets": {}}
    batched = _counts(args.batched, "--batched") if not args.quick else [1, 8, 64]
    result["batched"] = {}
    for net in NETS:  # first, before any AsyncVectorEnv's processes have run
        if progress is not None:
            progress(f"batched, {net} net: one version-1 environment, the batched vector env at {batched}")
        result["batched"][net] = batched_steps_per_second(batched, seconds, net=net)
    for net in NETS:
        if progress is not None:
            progress(f"{net} net: one environment, native vector env at {tables}, AsyncVectorEnv at {async_tables}")
        single = single_steps_per_second(seconds, net)
        rate = single["steps_per_s"]
        native = {n: native_steps_per_second(n, seconds, net) for n in tables}
        asynchronous = {n: async_steps_per_second(n, seconds, net) for n in async_tables}
        result["nets"][net] = {
            "single": single,
            "native": {str(n): {"steps_per_s": r, "ratio": r / rate} for n, r in native.items()},
            "async": {str(n): {"steps_per_s": r, "ratio": r / rate} for n, r in asynchronous.items()},
        }
    single = {net: result["nets"][net]["single"]["steps_per_s"] for net in NETS}
    result["cloth_cost"] = single["rigid"] / single["cloth"]
    if progress is not None:
        progress(f"players: pro and the Block bot, {args.ticks} ticks each")
    result["players"] = players_per_control_tick(args.ticks if not args.quick else 5_000)
    with open("/proc/loadavg") as f:
        result["loadavg_before_after"] = [load_before, float(f.read().split()[0])]
    return result


def _report(result: dict) -> None:
    print(f"environment steps per second (Return-v0 against novice, {result['seconds']:g} s each; "
          f"ratio to one environment of the same net):")
    for net, row in result["nets"].items():
        single = row["single"]
        print(f"  {net} net: one environment {single['steps_per_s']:.0f} steps/s "
              f"({single['physics_share']:.0%} of it in the physics)")
        for kind, label in (("native", "native vector env"), ("async", "AsyncVectorEnv")):
            for n, r in row[kind].items():
                print(f"    {label:<18} N = {n:>3}: {r['steps_per_s']:7.0f} steps/s  {r['ratio']:5.2f}x")
    for net, b in result["batched"].items():
        print(f"  batched (Return-v1, {net} net, hold; medians of {b['rounds']} turns each, ratios' range in "
              f"brackets): one environment {b['single']:.0f} steps/s")
        for n, r in b["batched"].items():
            low, high = r["ratio_range"]
            cloth = f", the cloth net's own steps {r['net_share']:.0%}" if net == "cloth" else ""
            print(f"    {'batched vector env':<18} N = {n:>3}: {r['steps_per_s']:7.0f} steps/s  {r['ratio']:5.2f}x "
                  f"[{low:.2f}-{high:.2f}]  (compiled call {r['compiled_share']:.0%}, AI profiles' decisions "
                  f"{r['decisions_share']:.0%}{cloth}; the compiled call alone: {r['compiled_alone_ratio']:.1f}x)")
    print(f"  the cloth net costs {result['cloth_cost']:.2f}x the rigid net's time per step (one environment)")
    p = result["players"]
    print(f"players per control tick (match_rigid, {p['pro']['ticks']} ticks): "
          f"pro {p['pro']['ai_us_per_control_tick']:.1f} us, "
          f"Block bot {p['block_bot']['ai_us_per_control_tick']:.1f} us ({p['ratio_bot_to_pro']:.2f}x), "
          f"its act() {p['block_bot']['act_us_per_decision']:.1f} us a decision")
    before, after = result["loadavg_before_after"]
    print(f"load average before/after: {before:.2f} / {after:.2f}")


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=4.0, help="wall seconds of each steps/s measurement")
    parser.add_argument("--tables", default="1,8,64", help="tables of the native vector env, N[,N...]")
    parser.add_argument("--async-tables", default="1,8,64", help="processes of the AsyncVectorEnv, N[,N...]")
    parser.add_argument("--batched", default="1,8,64,256", help="tables of the batched vector env, N[,N...]")
    parser.add_argument("--ticks", type=int, default=60_000, help="ticks of each players' match")


STUDY = Study(run=_run, report=_report, add_arguments=_arguments,
              quick="N = 1, 8 native, 1, 8, 64 batched and 2 AsyncVectorEnv, 1 s each, 5000-tick players' matches")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.env", "env"))
