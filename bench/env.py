"""What the training environment and the bot API cost: environment steps per second (one
environment, the cloth net beside the rigid one, Gymnasium's AsyncVectorEnv of N), and the
players' time per control tick, a bot's against the engine's AI's, in the same run.

- steps: Return-v0 against novice, `hold` actions at the ready pose (the agent never strikes, so
  each episode runs to the opponent's point or its truncation); resets included, the first
  episode (kernels loaded) not timed. AsyncVectorEnv: N environments in N processes
  (forkserver), steps of all N counted.
- players: the same in-process match (match_rigid, seed 0) with A played by `pro` and by
  examples/block.py:Block, B by novice, each --ticks ticks: engine.match.Match.ai_seconds (all
  the players' decisions and control laws) per control tick, and the bot's own act() (CPU) per
  decision.

`python -m bench.env [--seconds 5] [--vector 8] [--ticks 60000] [--json]`
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
READY = np.array([1.75, 0.0, 0.15, -1.0, 0.0, 0.0])  # a hold action: end B's ready pose


def steps_per_second(seconds: float, net: str = "rigid") -> float:
    """One environment's steps per second of wall time."""
    from engine.env import PingPongEnv

    env = PingPongEnv(opponent="novice", net=net)
    env.reset(seed=0)
    done = False
    while not done:  # the first episode loads the kernels
        _, _, terminated, truncated, _ = env.step(READY)
        done = terminated or truncated
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        _, _, terminated, truncated, _ = env.step(READY)
        steps += 1
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - started)


def vector_steps_per_second(n: int, seconds: float) -> float:
    """AsyncVectorEnv of n: environment steps (n a vector step) per second of wall time."""
    import gymnasium

    vector = gymnasium.vector.AsyncVectorEnv([lambda: gymnasium.make("engine.env:pingpong/Return-v0",
                                                                     opponent="novice")] * n,
                                             context="forkserver")
    try:
        vector.reset(seed=list(range(n)))
        actions = np.stack([READY] * n)
        for _ in range(300):  # past every worker's first episode (kernels loaded)
            vector.step(actions)
        steps, started = 0, time.perf_counter()
        while time.perf_counter() - started < seconds:
            vector.step(actions)  # an ended episode resets itself (autoreset)
            steps += n
        return steps / (time.perf_counter() - started)
    finally:
        vector.close()


def players_per_control_tick(ticks: int) -> dict:
    """Match.ai_seconds per control tick with A played by pro and by the Block bot (B: novice)."""
    from engine.match import Match, control_period, match_scene
    from engine.scene import load_scene

    base = load_scene("match_rigid")
    out = {}
    for name, player in (("pro", "pro"), ("block_bot", f"{EXAMPLES / 'block.py'}:Block")):
        match = Match(match_scene(base, player, "novice", best_of=5), seed=0)
        result = match.play(max_ticks=ticks)
        control_ticks = result.ticks // control_period(match.scene)
        seat = match.ais[0]
        out[name] = {"ticks": result.ticks, "ai_us_per_control_tick": 1e6 * match.ai_seconds / control_ticks,
                     "decisions_of_a": seat.decisions,
                     "act_us_per_decision": 1e6 * seat.act_seconds / seat.decisions if not seat.profile else None}
    out["ratio_bot_to_pro"] = out["block_bot"]["ai_us_per_control_tick"] / out["pro"]["ai_us_per_control_tick"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="wall seconds of each steps/s measurement")
    parser.add_argument("--vector", type=int, default=8, help="environments of the AsyncVectorEnv")
    parser.add_argument("--ticks", type=int, default=60_000, help="ticks of each players' match")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with open("/proc/loadavg") as f:
        load_before = float(f.read().split()[0])
    result = {
        "steps_per_s_rigid": steps_per_second(args.seconds),
        "steps_per_s_cloth": steps_per_second(args.seconds, "cloth"),
        f"steps_per_s_async_{args.vector}": vector_steps_per_second(args.vector, args.seconds),
        "players": players_per_control_tick(args.ticks),
    }
    with open("/proc/loadavg") as f:
        result["loadavg_before_after"] = [load_before, float(f.read().split()[0])]
    result["cloth_cost"] = result["steps_per_s_rigid"] / result["steps_per_s_cloth"]
    if args.json:
        print(json.dumps(result))
    else:
        print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
