"""Learn to return the ball by the cross-entropy method: no deep-learning framework, a policy of four numbers.

The policy plans one stroke for each ball that has bounced on its court (and serves as
examples/attack.py does, which Return-v0 never asks of it): it predicts where the
ball crosses its hitting line (free fall from the ball's state, no drag or spin) and drives the
bat through that point (engine.play.bot.target: a path the arm's PD law tracks), four learned numbers
deciding how:

    params = (line, pace, lift, tilt): the hitting line (m behind the table's centre), the bat's
    speed through the ball towards the net and upwards (m/s), the face normal's z over its x.

`python examples/cem.py` trains on pingpong/Return-v0 against novice (seeded: the same curve on
every run of the same code), then judges what it learned on episodes it never trained on: the
best candidate of the training episodes and the final mean, each on VALIDATION_EPISODES new
seeds, the better one kept; that one and the untrained START_MEAN on TEST_EPISODES more (the
score a reader may quote: the training score overstates, having been chosen on those very
episodes). It writes the learning curve (cem_curve.png) and the parameters kept
(cem_params.json, with the held-out scores) into --out, and plays them against novice:

    pingpong match --scene match_rigid --a examples/cem.py:Learned --b novice --best-of 1

Learned plays the cem_params.json beside this file, or the one the CEM_PARAMS environment
variable names (main() sets it to its --out's).

The cross-entropy method (Rubinstein 1999; Szita and Lorincz 2006 for control): sample a
population of parameters from a normal distribution, play each on the same seeded episodes, refit
the distribution's mean and standard deviation to the best ELITE of them, repeat.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from engine.play.bot import Bot, target
from engine.play.rules import Phase

GRAVITY = 9.81  # m/s^2
PARAMS_FILE = Path(__file__).with_name("cem_params.json")
PARAMS_ENV = "CEM_PARAMS"  # the parameters file Learned plays, if set
VALIDATION_EPISODES = 16  # new seeds that choose between the best candidate and the final mean
TEST_EPISODES = 32  # more new seeds that score the choice and the untrained start
START_MEAN = np.array([1.5, 2.0, 1.0, 0.2])  # line m, pace m/s, lift m/s, tilt
START_STD = np.array([0.2, 1.0, 0.6, 0.3])
OPPONENT = "novice"


class Policy:
    """The policy of `params` at end `end_sign`: from an OBSERVATION_DTYPE record, the action vector
    of Return-v0's "target" actions (pose, face normal, velocity, time to reach the pose). The
    same vector is returned until the stroke is played, so the path is kept."""

    def __init__(self, params, end_sign: int):
        self.line, self.pace, self.lift, self.tilt = (float(v) for v in params)
        self.end_sign = end_sign
        self.ready = np.array([end_sign * 1.75, 0.0, 0.15, -end_sign, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        self.vector, self.key, self.until = self.ready, None, -1.0

    def __call__(self, obs, player: int) -> np.ndarray:
        now = float(obs["time"])
        key = (int(obs["rally"]), int(obs["shots"]))
        if key == self.key and now < self.until:
            return self.vector  # the stroke planned for this ball: keep its path
        ball = obs["ball"]
        pos, vel = ball["pos"], ball["vel"]
        s = self.end_sign
        self.vector, self.key = self.ready, None
        mine, phase = int(obs["to_strike"]) == player, int(obs["phase"])
        if mine and phase == Phase.WAITING_SERVE and vel[2] < 0.0 and pos[2] < 0.35:  # a service, not learned:
            t = (vel[2] + np.sqrt(vel[2] ** 2 + 2 * GRAVITY * max(pos[2] - 0.16, 0.0))) / GRAVITY  # the toss at 16 cm
            if t > 0.03:
                self.vector = np.array([pos[0], pos[1], 0.16, -s, 0.0, -0.1, -s * 4.5, 0.0, 0.0, t])
                self.key, self.until = key, now + t + 0.1
        elif mine and phase == Phase.BOUNCED and vel[0] * s > 0.5:
            t = (s * self.line - pos[0]) / vel[0]
            if 0.03 < t < 0.8:
                hit = (s * self.line, pos[1] + vel[1] * t, max(pos[2] + vel[2] * t - 0.5 * GRAVITY * t * t, 0.03))
                self.vector = np.array([*hit, -s, 0.0, self.tilt, -s * self.pace, 0.0, self.lift, t])
                self.key, self.until = key, now + t + 0.1
        return self.vector


class Learned(Bot):
    """The policy with the parameters cem.py learned (cem_params.json beside this file, or $CEM_PARAMS)."""

    def setup(self, end, scene):
        path = Path(os.environ.get(PARAMS_ENV) or PARAMS_FILE)
        self.policy = Policy(json.loads(path.read_text())["params"], self.end_sign)
        self.shown = None
        self.action = None

    def act(self, obs):
        vector = self.policy(obs, self.player)
        if vector is not self.shown:  # a new stroke (or the ready pose): plan its path once
            self.shown = vector
            self.action = target(obs, vector[0:3], vector[3:6], vel=vector[6:9], at=float(obs["time"]) + vector[9])
        return self.action


def episode_return(env, params, seed: int) -> float:
    """One seeded episode of Return-v0 ("target" actions) played by the policy: its total reward."""
    env.reset(seed=seed)
    agent = env.unwrapped
    policy = Policy(params, -1 if agent.player == 0 else 1)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, _ = env.step(policy(agent.seat.view, agent.player))
        total += reward
        done = terminated or truncated
    return total


def train(iterations: int = 10, population: int = 16, elite: int = 4, episodes: int = 8, seed: int = 0,
          validation: int = VALIDATION_EPISODES, test: int = TEST_EPISODES) -> dict:
    """The cross-entropy method on Return-v0 against OPPONENT: per iteration the mean return of the
    population and of its elite; the parameters kept (the best candidate or the final mean,
    whichever scores more on `validation` new episodes) and, on `test` more, their mean return
    and the untrained START_MEAN's."""
    import gymnasium

    import engine.learning.env  # noqa: F401 - registers the environments (pyflakes: used by gymnasium.make)

    env = gymnasium.make("pingpong/Return-v0", opponent=OPPONENT, action_type="target")
    rng = np.random.default_rng(seed)
    mean, std = START_MEAN.copy(), START_STD.copy()
    curve, best, best_score = [], mean.copy(), -np.inf
    started = time.perf_counter()
    seeds = rng.integers(0, 2**31 - 1, episodes)  # every candidate of every iteration plays the same episodes
    for it in range(iterations):
        candidates = mean + std * rng.standard_normal((population, len(mean)))
        scores = np.array([np.mean([episode_return(env, c, int(s)) for s in seeds]) for c in candidates])
        order = np.argsort(scores)[::-1]
        chosen = candidates[order[:elite]]
        mean, std = chosen.mean(axis=0), chosen.std(axis=0) + 0.02  # a floor keeps it exploring
        if scores[order[0]] > best_score:
            best, best_score = candidates[order[0]].copy(), float(scores[order[0]])
        curve.append({"iteration": it, "population_mean": float(scores.mean()),
                      "elite_mean": float(scores[order[:elite]].mean()), "best": float(scores[order[0]])})
    # Held out: seeds no candidate trained on, drawn after the training seeds from the same stream.
    held_out = rng.integers(0, 2**31 - 1, validation + test)
    check, score = [int(s) for s in held_out[:validation]], [int(s) for s in held_out[validation:]]
    kept = max((best, mean), key=lambda p: np.mean([episode_return(env, p, s) for s in check]))
    trained = float(np.mean([episode_return(env, kept, s) for s in score]))
    untrained = float(np.mean([episode_return(env, START_MEAN, s) for s in score]))
    env.close()
    return {"curve": curve, "params": kept.tolist(), "training_score": best_score, "seed": seed,
            "held_out": {"episodes": test, "trained": trained, "untrained": untrained},
            "wall_seconds": time.perf_counter() - started,
            "settings": {"iterations": iterations, "population": population, "elite": elite, "episodes": episodes,
                         "validation": validation}}


def curve_png(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    its = [row["iteration"] for row in result["curve"]]
    fig, ax = plt.subplots(figsize=(6, 4))
    for key in ("population_mean", "elite_mean", "best"):
        ax.plot(its, [row[key] for row in result["curve"]], marker="o", label=key.replace("_", " "))
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"return per episode (Return-v0 against {OPPONENT})")
    ax.set_title(f"cross-entropy method, seed {result['seed']}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--population", type=int, default=16)
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(Path(__file__).parent), help="directory of the curve and the parameters")
    args = parser.parse_args()
    result = train(args.iterations, args.population, 4, args.episodes, args.seed)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    curve_png(result, out / "cem_curve.png")
    params_file = out / "cem_params.json"
    params_file.write_text(json.dumps(result, indent=1))
    from engine.physics.scene import load_scene
    from engine.play.match import match_record

    os.environ[PARAMS_ENV] = str(params_file.resolve())  # Learned plays what was just learned
    record = match_record(load_scene("match_rigid"), 0, f"{Path(__file__).resolve()}:Learned", "novice", best_of=1)
    print(json.dumps({"curve": result["curve"], "params": result["params"], "held_out": result["held_out"],
                      "wall_seconds": result["wall_seconds"],
                      "match_against_novice": {k: record[k] for k in ("winner", "points", "reasons")}}, indent=1))


if __name__ == "__main__":
    main()
