"""Train a bot with PPO (stable-baselines3) on pingpong/Return-v1, then let it play novice.

    make train                                   # the extra: stable-baselines3, torch's CPU build
    python examples/train_ppo.py --steps 2000000 --out runs/ppo
    python examples/train_ppo.py --task strike --steps 60000 --envs 2 --out runs/strike

--task strike learns the stroke only, on examples/strike.py's StrikeEnv (one return a step, the
footwork examples/drive.py's), and its bot is examples/strike.py:StrikeBot.

The environment is the one made for learners (engine/learning/agent_frame.py: the agent's own frame,
bounded observations, actions in [-1, 1]) with the dense reward (engine/learning/env.py REWARD_TERMS),
against `novice`: with `hold` actions (the default) --envs tables of the batched vector env in
this process (engine/learning/vector_env.py, every table's step in one numba call) behind
stable-baselines3's VecEnv API (tables_vec_env); otherwise, and for --task strike, one
environment per process (stable-baselines3's SubprocVecEnv, forkserver: numba's threads make
fork() unsafe). Rewards normalised by VecNormalize (observations are bounded already). A rollout
is about 4096 steps whatever --envs; PPO's defaults otherwise (Schulman et al. 2017;
stable-baselines3's hyper-parameters). At the end it writes into --out:

- ppo_policy.zip and ppo_policy.json (the policy, and the action type examples/ppo_bot.py plays);
- ppo_curve.png, the mean return of the finished episodes along the steps;
- ppo_summary.json: steps, wall time, steps per second, and on EVAL_EPISODES held-out seeds the
  mean return and the share of episodes whose return landed, then a best-of-3 match of
  examples/ppo_bot.py:PPOBot against novice.

`--steps 4096 --envs 1` is the smoke run the tests make: it trains, saves, and the saved bot plays.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ENV_ID = "pingpong/Return-v1"
OPPONENT = "novice"
EVAL_EPISODES = 100  # held-out seeds for the summary's return and landed share
EVAL_SEED = 1_000_000  # held-out seeds start here: training draws its own from --seed
TABLES = 16  # Return-v1's default environments: tables of the batched vector env, stepped together


def _beside(name: str):
    """The module examples/NAME.py beside this file, imported as a file bot's imports find it."""
    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.insert(0, here)
    return importlib.import_module(name)


def new_env(task: str, action_type: str, reward: str = "dense"):
    """One environment of the task: Return-v1 against OPPONENT, or examples/strike.py's StrikeEnv."""
    import gymnasium

    if task == "strike":
        return _beside("strike").StrikeEnv()
    # "module:id" imports the registration in each worker process too
    return gymnasium.make(f"engine.learning.env:{ENV_ID}", opponent=OPPONENT, action_type=action_type, reward=reward)


def batched(task: str, action_type: str) -> bool:
    """Whether the task's environments are the batched vector env's tables (Return-v1, hold)."""
    return task == "return" and action_type == "hold"


def tables_vec_env(tables: int, seed: int):
    """Return-v1 (hold, dense reward, against OPPONENT) as `tables` tables of the batched vector env
    (engine/learning/vector_env.py: every table's step in one numba call) behind stable-baselines3's
    VecEnv API, which resets an ended episode's table in the step that ended it (the last
    observation in the info's "terminal_observation") where Gymnasium's vector env resets it at
    the next step."""
    import gymnasium
    from stable_baselines3.common.vec_env import VecEnv

    from engine.learning.vector_env import PingPongVectorEnv  # registers the ids

    class TablesVecEnv(VecEnv):
        def __init__(self):
            self.vector = PingPongVectorEnv(tables, opponent=OPPONENT, reward="dense", version=1,
                                            max_episode_steps=gymnasium.spec(ENV_ID).max_episode_steps)
            super().__init__(tables, self.vector.single_observation_space, self.vector.single_action_space)
            self.seed(seed)

        def reset(self):
            seeds = None if all(s is None for s in self._seeds) else self._seeds
            obs, _ = self.vector.reset(seed=seeds)
            self._reset_seeds()
            return obs

        def step_async(self, actions):
            self.actions = actions

        def step_wait(self):
            obs, rewards, terminated, truncated, _ = self.vector.step(self.actions)
            dones = terminated | truncated
            infos = [{"TimeLimit.truncated": bool(truncated[k] and not terminated[k])} for k in range(tables)]
            if dones.any():
                for k in np.flatnonzero(dones):
                    infos[k]["terminal_observation"] = obs[k].copy()
                fresh, _ = self.vector.reset(options={"reset_mask": dones})
                obs[dones] = fresh[dones]
            return obs, rewards.astype(np.float32), dones, infos

        def close(self):
            self.vector.close()

        def get_attr(self, attr_name, indices=None):
            return [getattr(self.vector.envs[k], attr_name) for k in self._get_indices(indices)]

        def set_attr(self, attr_name, value, indices=None):
            for k in self._get_indices(indices):
                setattr(self.vector.envs[k], attr_name, value)

        def env_method(self, method_name, *args, indices=None, **kwargs):
            return [getattr(self.vector.envs[k], method_name)(*args, **kwargs) for k in self._get_indices(indices)]

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False for _ in self._get_indices(indices)]

    return TablesVecEnv()


def make_env(task: str, action_type: str, seed: int, envs: int):
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

    if batched(task, action_type):
        return VecNormalize(VecMonitor(tables_vec_env(envs, seed)), norm_obs=False, norm_reward=True)
    vec_cls, vec_kwargs = (SubprocVecEnv, {"start_method": "forkserver"}) if envs > 1 else (DummyVecEnv, None)
    vec = make_vec_env(lambda: new_env(task, action_type), n_envs=envs, seed=seed, vec_env_cls=vec_cls,
                       vec_env_kwargs=vec_kwargs)
    return VecNormalize(vec, norm_obs=False, norm_reward=True)


def evaluate(model, task: str, action_type: str, episodes: int) -> dict:
    """The deterministic policy on `episodes` held-out seeds of the task (Return-v1's sparse
    reward): mean return, and the share of episodes whose return bounced on the opponent's court."""
    env = new_env(task, action_type, reward="sparse")
    returns, landed = [], 0
    for k in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED + k)
        total, done, info = 0.0, False, {}
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns.append(total)
        # RETURN_LANDED: the return bounced on the opponent's court (StrikeEnv says so)
        landed += info["landed"] if task == "strike" else total >= 1.0
    env.close()
    return {"episodes": episodes, "mean_return": float(np.mean(returns)), "landed_share": landed / episodes}


def curve_png(points: list[tuple[int, float]], path: Path, task: str = "return") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    if points:
        steps, means = zip(*points)
        ax.plot(steps, means, marker=".")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("mean return (last episodes)")
    env = "examples/strike.py StrikeEnv" if task == "strike" else ENV_ID
    ax.set_title(f"PPO (stable-baselines3): {env} against {OPPONENT}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def train(steps: int, envs: int, out: Path, seed: int = 0, action_type: str = "hold",
          eval_episodes: int = EVAL_EPISODES, best_of: int = 3, task: str = "return") -> dict:
    """Train, save, evaluate, play a match (see the module's docstring); the summary."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    out.mkdir(parents=True, exist_ok=True)
    curve: list[tuple[int, float]] = []

    class Curve(BaseCallback):
        def _on_rollout_end(self) -> None:
            finished = [info["r"] for info in self.model.ep_info_buffer]
            if finished:
                curve.append((self.num_timesteps, float(np.mean(finished))))

        def _on_step(self) -> bool:
            return True

    import torch

    torch.set_num_threads(1)  # a small MLP: torch's thread pool would only fight the environments for the cores
    vec = make_env(task, action_type, seed, envs)
    # A rollout of about 4096 steps whatever the number of environments; a strike is a one-step
    # episode: shorter rollouts update the policy more often.
    n_steps = max(64, min((512 if task == "strike" else 4096) // envs, steps // envs))
    # A strike's action has a prior (examples/strike.py maps 0 to a plain drive): explore near it.
    extra = {"policy_kwargs": {"log_std_init": -0.5}} if task == "strike" else {}
    model = PPO("MlpPolicy", vec, seed=seed, device="cpu", verbose=0, n_steps=n_steps,
                batch_size=min(256 if task != "strike" else 64, n_steps * envs), **extra)
    started = time.perf_counter()
    model.learn(total_timesteps=steps, callback=Curve())
    wall = time.perf_counter() - started
    vec.close()
    policy = out / ("strike_policy.zip" if task == "strike" else "ppo_policy.zip")
    model.save(policy)
    what = {"task": "strike", "env": "examples/strike.py StrikeEnv"} if task == "strike" else {
        "task": "return", "env": ENV_ID, "action_type": action_type}  # the action type ppo_bot.py plays
    policy.with_suffix(".json").write_text(json.dumps({**what, "opponent": OPPONENT, "steps": int(model.num_timesteps),
                                                       "seed": seed}))
    curve_png(curve, out / "ppo_curve.png", task)
    summary = {"task": task, "steps": int(model.num_timesteps), "envs": envs, "wall_seconds": wall,
               "steps_per_second": model.num_timesteps / wall,
               "held_out": evaluate(model, task, action_type, eval_episodes)}
    from engine.physics.scene import load_scene
    from engine.play.match import match_record

    # the bot plays what was just trained
    os.environ["STRIKE_POLICY" if task == "strike" else "PPO_POLICY"] = str(policy.resolve())
    bot = (f"{Path(__file__).resolve().with_name('strike.py')}:StrikeBot" if task == "strike"
           else f"{Path(__file__).resolve().with_name('ppo_bot.py')}:PPOBot")
    record = match_record(load_scene("match_rigid"), seed, bot, OPPONENT, best_of=best_of)
    summary["match_against_novice"] = {k: record[k] for k in ("winner", "games", "points", "reasons")}
    (out / "ppo_summary.json").write_text(json.dumps(summary, indent=1))
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="environment steps to train for")
    parser.add_argument("--envs", type=int, default=None,
                        help="environments: tables of the batched vector env in this process for Return-v1 with "
                             f"hold actions (default {TABLES}), else one process each (default 2)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--action-type", choices=["hold", "target", "force"], default="hold",
                        help="Return-v1's action type (--task return)")
    parser.add_argument("--task", choices=["return", "strike"], default="return",
                        help="return: Return-v1, the whole arm; strike: the stroke only (examples/strike.py)")
    parser.add_argument("--out", default="runs/ppo", help="directory of the policy, the curve and the summary")
    args = parser.parse_args()
    envs = args.envs if args.envs is not None else (TABLES if batched(args.task, args.action_type) else 2)
    if envs < 1:
        parser.error(f"--envs {envs}: give a positive number of environments")
    print(json.dumps(train(args.steps, envs, Path(args.out), args.seed, args.action_type, task=args.task),
                     indent=1))


if __name__ == "__main__":
    main()
