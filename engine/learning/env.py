"""The Gymnasium environments: one bat of an in-process match as the agent, through the bot API.

    import gymnasium
    import engine.learning.env  # registers pingpong/Return-v1 and pingpong/Rally-v1 (and the v0 ids)

    env = gymnasium.make("pingpong/Return-v1")            # or Rally-v1, opponent="novice", reward="dense"
    obs, info = env.reset(seed=0)

"engine.learning.env:pingpong/Return-v0" imports the module itself (what a vector environment's worker
processes need). gymnasium.vector.AsyncVectorEnv steps N of them in N processes; use its
context="forkserver" (numba's threads make fork() after a kernel has run unsafe).

The agent is a bot (engine.play.bot.Bot) in an engine.play.match.Match, at its end's seat: each step is
one control period; its action is an ACTION_DTYPE record made from the action vector, checked
and played exactly as a bot's (engine.play.players.Seat), from the control tick a decision delay
after the observation it answers (CompiledScene.decision_delay: the scene's
match.decision_latency, a player's reaction), and the observation vector is the bot's
OBSERVATION_DTYPE record, field by field (OBSERVATION_NAMES). Rewards and ends come from the
referee: the agent's strikes, its returns bouncing on the opponent's court, the point.

- Return-v0: return the opponent's service or drive. An episode starts with the opponent's
  service, or (half of them, drawn from the seed) with a drive: an AI of the opponent's profile
  plays the agent's end until the opponent strikes a return, then the agent takes over. Reward
  RETURN_STRIKE for striking the ball, RETURN_LANDED when the return bounces on the opponent's
  court, which ends the episode; it also ends when the rally is decided otherwise.
- Rally-v0: a rally against the opponent from its service: RETURN_LANDED for each return that
  bounces on its court, then +1 for the point won, -1 for the point lost.

Version 1 (Return-v1, Rally-v1) is made for learners (engine.learning.agent_frame): the observation in
the agent's own frame (A and B see the same game), every entry scaled into [-1, 1], no tick or
clock, the phase and who strikes next as one-hots; actions in [-1, 1] mapped onto the agent's
half of the playing space and the arm's limits; a time limit the registry knows
(max_episode_steps: 3 s of play for Return, 20 s for Rally); reward="dense" adds shaping terms
to the sparse ones (REWARD_TERMS). Version 0 keeps the world-frame record and the raw action
vectors of before. In both a wrong action shape is a ValueError that names the expected one,
and a step after the episode ended (terminated or truncated) a RuntimeError.

A curriculum (Return only): ball_speed=(lo, hi) m/s and ball_spin=(lo, hi) rad/s replace the
opponent's service by a ball machine's ball (engine.learning.ball_machine): shot from behind the
opponent's end line at the agent's court, at a horizontal speed and a topspin (+) or backspin
(-) drawn from the ranges, as if the opponent had just returned it; only a ball whose first
contact is the agent's court is played (drawn anew otherwise, MACHINE_TRIES times at most).
Start slow and spinless; widen the ranges as the agent returns them.

Dense reward (reward="dense"), per end, on top of the task's own rewards: APPROACH times the
fall of the distance between the agent's bat centre and the ball over the step while the agent
is to strike next (potential-based shaping, Ng, Harada and Russell 1999, "Policy invariance
under reward transformations": it leaves the best policy as it is); NET_CLEAR when the agent's
shot crosses the net's plane towards the opponent; +1 for a point won and -1 for a point lost
(Rally's own, now also Return's).

The rigid net by default; net="cloth" plays the cloth net in this process (the default match's
85 x 8 knots). render_mode "rgb_array" draws the episode as the replay's picture
(engine.tools.render.rgb); write_replay(path) writes it as a replay file for `pingpong replay FILE
--html PAGE` (the browser's 3D replay) or `--png`/`--gif`.
"""
from __future__ import annotations

import math
from dataclasses import replace

import gymnasium
import numpy as np
from gymnasium import spaces

from engine.learning import agent_frame, ball_machine
from engine.play.bot import Bot, force, hold, new_action, target
from engine.physics.dtypes import CONTACT_DTYPE, OBSERVATION_DTYPE, POINT_DTYPE, physics_snapshot_dtype
from engine.physics.scene import load_scene, scene_toml
from engine.physics.compiled import CompiledScene, compile_scene
from engine.physics.world import new_events, step
from engine.play.ai import SKILLS
from engine.play.ai.player import think_scratch
from engine.play.ai.profile_bot import ProfileBot
from engine.play.match import Match, match_scene, point_row
from engine.play.players import decision_key
from engine.play.rules import Phase
from engine.tools import render
from engine.tools import replay as replay_file
from net_kernel.sim import compile_kernels

RETURN_STRIKE = 0.2  # reward for striking the ball
RETURN_LANDED = 1.0  # reward for a return that bounces on the opponent's court
APPROACH = 0.5  # dense reward per metre the bat closes on the ball while the agent is to strike
NET_CLEAR = 0.3  # dense reward for the agent's shot crossing the net's plane towards the opponent
REWARD_TERMS = ("sparse", "dense")
MACHINE_TRIES = 50  # balls the machine may draw for one episode before the ranges are called impossible
MACHINE_SPEED = (1.0, 30.0)  # m/s: the horizontal speeds a machine's range may ask for
MACHINE_SPIN = (-600.0, 600.0)  # rad/s: ~95 rev/s either way, as a strong loop or chop
MAX_EPISODE_STEPS = {"return": 300, "rally": 2000}  # version 1's time limits: 3 s and 20 s at 100 Hz
FRAME_EVERY = 10  # ticks between the episode's kept frames (render, write_replay)
SCENES = {"rigid": "match_rigid", "cloth": "match"}
ACTIONS = ("hold", "target", "force")


def _observation_layout():
    """(name, low, high) of each number of the observation vector, in OBSERVATION_DTYPE's order."""
    big = np.inf
    bat = [("pos", 8.0, 3), ("quat", 1.0, 4), ("vel", 100.0, 3), ("ang_vel", 2000.0, 3)]
    rows = [("tick", 0.0, big)] + [("time", 0.0, big)]
    rows += [(f"ball.{name}[{i}]", -bound, bound) for name, bound in (("pos", 8.0), ("vel", 100.0), ("spin", 2000.0))
             for i in range(3)]
    rows += [(f"{who}.{name}[{i}]", -bound, bound) for who in ("own", "other") for name, bound, n in bat
             for i in range(n)]
    rows += [(f"{name}[{i}]", 0.0, big) for name in ("score", "games_won") for i in range(2)]
    rows += [("phase", 0.0, float(Phase.OVER)), ("server", 0.0, 1.0), ("to_strike", -1.0, 1.0), ("shots", 0.0, big),
             ("rally", 0.0, big)]
    return rows


_LAYOUT = _observation_layout()
OBSERVATION_NAMES = tuple(name for name, _, _ in _LAYOUT)  # the observation vector's entries
_FLOATS_AT = OBSERVATION_DTYPE.fields["time"][1]  # time, ball, own, other: 36 float64 words from here


def observation_space() -> spaces.Box:
    """The observation vector's space: OBSERVATION_DTYPE's fields flattened (OBSERVATION_NAMES)."""
    low = np.array([lo for _, lo, _ in _LAYOUT])
    high = np.array([hi for _, _, hi in _LAYOUT])
    return spaces.Box(low, high, dtype=np.float64)


def flatten(observation, out: np.ndarray) -> np.ndarray:
    """An OBSERVATION_DTYPE record into the observation vector `out` (len(OBSERVATION_NAMES),)."""
    out[0] = observation["tick"]
    out[1:37] = observation.reshape(1).view(np.uint8)[_FLOATS_AT:_FLOATS_AT + 36 * 8].view(np.float64)
    out[37:39], out[39:41] = observation["score"], observation["games_won"]
    out[41], out[42], out[43] = observation["phase"], observation["server"], observation["to_strike"]
    out[44], out[45] = observation["shots"], observation["rally"]
    return out


def distance(a, b) -> float:
    """|a - b| of two 3-vectors (m), the squares summed in order: the batched environment's arithmetic
    (engine.learning.batch), bit for bit (a BLAS norm's fused multiply-adds give other last bits)."""
    dx, dy, dz = float(a[0]) - float(b[0]), float(a[1]) - float(b[1]), float(a[2]) - float(b[2])
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def action_space(action_type: str, arm: str = "pro") -> spaces.Box:
    """The action vector's space. hold: the pose (m, inside the playing space) and the face normal
    (any non-zero vector; normalised) of engine.play.bot.hold; target: those, then the velocity (m/s)
    to reach the pose with and in how long (s) (engine.play.bot.target, then holding the pose; the same
    vector again keeps the path planned when it was first given, so that the path is played);
    force: force (N) and torque (N m), each component within the arm's limit over sqrt(3), so
    every vector is within the arm's limits."""
    if action_type in ("hold", "target"):
        low = [-3.0, -2.0, -0.5, -1.0, -1.0, -1.0]
        high = [3.0, 2.0, 1.5, 1.0, 1.0, 1.0]
        if action_type == "target":
            low, high = low + [-20.0, -20.0, -20.0, 0.0], high + [20.0, 20.0, 20.0, 1.0]
        return spaces.Box(np.array(low), np.array(high), dtype=np.float64)
    skill = SKILLS[arm]
    high = np.array([skill.max_force_n] * 3 + [skill.max_torque_nm] * 3) / np.sqrt(3.0)
    return spaces.Box(-high, high, dtype=np.float64)


class Agent(Bot):
    """The environment's bot: it plays the action the environment was last given, or, while
    `stand_in` is set, lets that engine AI play (the lead-in of a drive)."""

    budget_s = float("inf")  # the agent's decision is the environment's (and a stand-in's, the AI's): no budget

    def setup(self, end, scene):
        self.action = new_action()
        hold(scene.bats[end].pos, self.normal, self.action)  # where the bat starts, until the first action
        self.stand_in: ProfileBot | None = None

    def act(self, observation):
        if self.stand_in is not None:
            return self.stand_in.act(observation)
        return self.action


class PingPongEnv(gymnasium.Env):
    """One bat of a match as a Gymnasium environment (see the module's docstring).

    Args:
        task: "return" (Return-v0) or "rally" (Rally-v0). opponent: its AI profile, or None: a
            second agent at the other end (the two-bat rally of engine.learning.parallel_env).
        player: the agent's end, 0 (A) or 1 (B). net: "rigid" or "cloth".
        action_type: "hold" or "force" (action_space); the agent's arm is Agent.arm's (pro).
        max_seconds: simulated seconds before an episode is truncated.
        render_mode: None or "rgb_array". record: keep the episode's frames and contacts for
            write_replay (always with rgb_array).
        version: 0 (world-frame record, raw action vectors) or 1 (engine.learning.agent_frame).
        reward: "sparse" (the task's) or "dense" (with the shaping terms of the module's docstring).
        ball_speed, ball_spin: the ball machine's ranges (the curriculum of the module's
            docstring), m/s and rad/s; None, None: the opponent serves or drives.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 100 // FRAME_EVERY}

    def __init__(self, task: str = "return", opponent: str = "pro", player: int = 1, net: str = "rigid",
                 action_type: str = "hold", max_seconds: float | None = None,
                 render_mode: str | None = None, record: bool = False, version: int = 0, reward: str = "sparse",
                 ball_speed: tuple[float, float] | None = None, ball_spin: tuple[float, float] | None = None):
        if task not in ("return", "rally"):
            raise ValueError(f"task: must be return or rally, got {task!r}")
        if opponent not in SKILLS and not (opponent is None and task == "rally"):
            raise ValueError(f"opponent: an AI profile out of {', '.join(SKILLS)}, got {opponent!r}")
        if player not in (0, 1) or net not in SCENES or action_type not in ACTIONS:
            raise ValueError(f"player 0 or 1, net rigid or cloth, action_type hold or force; got {player!r}, "
                             f"{net!r}, {action_type!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode: None or rgb_array, got {render_mode!r}")
        if version not in (0, 1) or reward not in REWARD_TERMS:
            raise ValueError(f"version 0 or 1, reward sparse or dense; got {version!r}, {reward!r}")
        self.version, self.reward = version, reward
        self.machine = None
        if ball_speed is not None or ball_spin is not None:
            if task != "return" or opponent is None:
                raise ValueError("ball_speed and ball_spin (the ball machine) are a curriculum of the return task "
                                 "against an opponent")
            self.machine = (ball_machine.check_range("ball_speed", ball_speed or (8.0, 8.0), *MACHINE_SPEED),
                            ball_machine.check_range("ball_spin", ball_spin or (0.0, 0.0), *MACHINE_SPIN))
            flight = match_scene(load_scene(SCENES["rigid"]), "pro", "pro", best_of=1)
            flight = replace(flight, effects=flight.effects - {"ai", "referee"}, match=None,
                             bats=tuple(replace(bat, skill=None) for bat in flight.bats))
            flight = compile_scene(flight)
            self._flight = (flight.model, flight.initial_state(), new_events())
        self.task, self.opponent, self.player, self.net = task, opponent, player, net
        self.action_type, self.render_mode = action_type, render_mode
        self.record = record or render_mode == "rgb_array"
        self.max_seconds = (3.0 if task == "return" else 20.0) if max_seconds is None else max_seconds
        self.base = load_scene(SCENES[net])
        if version == 1:
            self.observation_space = agent_frame.observation_space()
            self.action_space = agent_frame.action_space(action_type)
        else:
            self.observation_space = observation_space()
            self.action_space = action_space(action_type, Agent.arm)
        self.ends = (player,) if opponent is not None else (0, 1)  # the agents' ends
        self._obs = np.zeros(self.observation_space.shape)
        self._ended = False
        self.match: Match | None = None
        self._compiled: dict[int, CompiledScene] = {}  # _new_match's scenes, by first server
        # The matches and lead-in stand-ins of earlier episodes, by first server: the next one of
        # that server renews one (Match.renew, ProfileBot.renew) instead of making it anew.
        self._matches: dict[int, Match] = {}
        self._stand_ins: dict[int, ProfileBot] = {}
        self._think_scratch: tuple | None = None  # the AI profiles' arrays, when shared (share_scenes)
        self.seed_of_match = 0
        self._warm = False

    def share_scenes(self, other: "PingPongEnv") -> None:
        """Use other's compiled match scenes (one a first server), built once for both, and the
        arrays its AI profiles think in (BatAI.use_scratch: they think a stroke out at once, and
        environments stepped in one thread never at the same time): other has the same net,
        opponent, player and agent (the vector env's tables do)."""
        if (other.net, other.opponent, other.player, other.ends) != (self.net, self.opponent, self.player, self.ends):
            raise ValueError("share_scenes: the other environment plays another scene, opponent or end")
        self._compiled = other._compiled
        if other._think_scratch is None:
            other._think_with(think_scratch(other.base.dt))
        self._think_with(other._think_scratch)

    def _think_with(self, scratch: tuple) -> None:
        """The AI profiles of this environment's matches and stand-ins think in `scratch`."""
        self._think_scratch = scratch
        for match in self._matches.values():
            match.ais.use_scratch(scratch)
        for stand_in in self._stand_ins.values():
            stand_in.ai.use_scratch(scratch)

    # --- episodes ---------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        lead_in = self.begin_episode(seed)
        while lead_in and not self._lead_in():  # a lead-in whose game ended first: the next match
            self.next_match()
        self.end_lead_in()
        return self.observation(), self.episode_info()

    def begin_episode(self, seed: int | None = None) -> bool:
        """reset() up to a drive's lead-in: the episode's draws and its first match; whether the
        lead-in is to be played (the stand-in then plays the agent's bat until the opponent drove:
        _lead_in, or the batch's engine.learning.batch). A lead-in whose game ends before the
        opponent returned once is played anew in the next match (next_match)."""
        super().reset(seed=seed)
        self.steps = 0
        self._ended = False
        self._shot = None
        if self.machine is not None:
            self._drive, self._server = False, self.player
            self.next_match()
            self._shot = self._machine_ball()
            return False
        self._drive = self.task == "return" and bool(self.np_random.integers(0, 2))
        self._server = int(self.np_random.integers(0, 2)) if self.opponent is None else None  # two agents: drawn
        self.next_match()
        return self._drive

    def next_match(self) -> None:
        """The episode's next match from its next seed; for a drive, the opponent's profile (a
        ProfileBot seeded from the match) stands in at the agent's bat for the lead-in."""
        server = self._new_match(int(self.np_random.integers(0, 2**31 - 1)), self._drive, self._server)
        if self._drive:
            seed = self.seed_of_match * 1000 + 7
            stand_in = self._stand_ins.get(server)
            if stand_in is None:
                stand_in = self._stand_ins[server] = ProfileBot(self.match.model, self.player, SKILLS[self.opponent],
                                                                self.opponent, seed=seed, control_every=self.every)
                if self._think_scratch is not None:
                    stand_in.ai.use_scratch(self._think_scratch)
            else:
                stand_in.renew(seed)
            agent = self.agent
            stand_in.player, stand_in.end_sign, stand_in.normal = agent.player, agent.end_sign, agent.normal
            agent.stand_in = stand_in

    def end_lead_in(self) -> None:
        """The agent takes its bat back from the stand-in (the lead-in is over)."""
        self.agent.stand_in = None

    def episode_info(self) -> dict:
        """The info reset() returns: a drive or not, the ball machine's ball, the match's seed and first server."""
        info = {"drive": self._drive, "match_seed": self.seed_of_match, "server": self.match.scene.match.first_server}
        if self._shot is not None:
            info["machine"] = self._shot
        return info

    def _machine_ball(self) -> dict:
        """The ball machine's ball as the opponent's return in the air (the agent served): drawn
        until one's first contact is the agent's court; what it was."""
        speed, spin = self.machine
        sign = -1 if self.player == 0 else 1
        model, state, events = self._flight
        for _ in range(MACHINE_TRIES):
            pos, vel, spin_vec = ball_machine.launch(self.np_random, sign, speed, spin)
            if ball_machine.lands_on(model, state, events, pos, vel, spin_vec, sign):
                break
        else:
            raise RuntimeError(f"ball machine: none of {MACHINE_TRIES} balls of speed {speed} m/s and spin {spin} "
                               "rad/s landed on the agent's court; narrow the ranges")
        record = np.zeros(1, physics_snapshot_dtype(len(self.match.scene.bats)))
        self.match.save(record)
        row = record[0]
        row["ball"]["pos"], row["ball"]["vel"], row["ball"]["spin"] = pos, vel, spin_vec
        row["rally"]["phase"], row["rally"]["striker"], row["rally"]["shots"] = Phase.STRUCK, 1 - self.player, 2
        self.match.restore(row, [])
        return {"speed": float(np.hypot(*vel[:2])), "spin": float(spin_vec @ np.array([-vel[1], vel[0], 0.0]))
                / float(np.hypot(*vel[:2]))}

    def _new_match(self, seed: int, drive: bool, server: int | None = None) -> int:
        """A best-of-1 match of the agent against the opponent, its first server the opponent (or,
        for a drive, the agent's end; or `server`); returns that server."""
        if server is None:
            server = self.player if drive else 1 - self.player
        compiled = self._compiled.get(server)
        if compiled is None:  # one compiled scene a first server: the model is read, never written, by a match
            agent_spec = f"{__name__}:Agent"
            ends = [agent_spec if end in self.ends else self.opponent for end in (0, 1)]
            scene = match_scene(self.base, *ends, best_of=1)
            scene = replace(scene, match=replace(scene.match, first_server="ab"[server]))
            compiled = self._compiled[server] = compile_scene(scene)
        self.seed_of_match = seed
        self.match = self._matches.get(server)
        if self.match is None:
            self.match = self._matches[server] = Match(compiled, seed=seed)
            if self._think_scratch is not None:
                self.match.ais.use_scratch(self._think_scratch)
        else:
            self.match.renew(seed)
        self.every = self.match.compiled.control_period
        self.seats = {end: self.match.ais[end] for end in self.ends}
        self.seat = self.seats[self.player]
        self.agent: Agent = self.seat.bot
        self._last_actions: dict = {}
        self.frames: list = []
        self.events: list = []
        self._keep_frame()
        if not self._warm:  # load (or compile) every kernel an episode calls now, not in the middle of one
            match = self.match
            step(match.model, match.state, None, match.events, dt=0.0)  # the tick kernels, as Match.play does
            if match.compiled.topology is not None:
                compile_kernels(match.compiled.topology, match.model.dt)  # the cloth net's, on a throwaway net
            match.ais.warm_up()
            self._warm = True
        return server

    def _lead_in(self) -> bool:
        """The stand-in plays the agent's end until the opponent drives the ball back; whether it
        did before the match ended."""
        while not self._opponent_drove():
            if self.match.over:
                return False
            self._advance()
        return True

    def _opponent_drove(self) -> bool:
        """The opponent has struck a return that the agent must now play (a new rally is tried
        again if the lead-in's rally was decided first)."""
        ref = self.match.referee
        return ref.shots >= 2 and ref.striker == 1 - self.player and ref.phase in (Phase.STRUCK, Phase.BOUNCED)

    def step(self, action):
        if self.match is None:
            raise RuntimeError("PingPongEnv.step: call reset() first")
        if self._ended or self.match.over:
            raise RuntimeError("PingPongEnv.step: the episode has ended (terminated or truncated); call reset()")
        self.act(self.player, action)
        rewards, decided, landed = self.play_period()
        terminated = decided or (self.task == "return" and landed[self.player])
        self.steps += 1
        truncated = not terminated and self.steps * self.every * self.match.model.dt >= self.max_seconds
        self._ended = terminated or truncated
        info = {"points": len(self.match.referee.points), "bot_errors": list(self.match.bot_errors)}
        return self.observation(), rewards[self.player], terminated, truncated, info

    def act(self, end: int, action) -> None:
        """The action vector into the action record of the agent at `end`."""
        seat = self.seats[end]
        agent = seat.bot
        if self.version == 1:
            a = agent_frame.checked_action(action, self.action_type)
            last = self._last_actions.get(end)
            arm = SKILLS[agent.arm]
            agent_frame.action_record(a, self.action_type, end, arm.max_force_n, arm.max_torque_nm, seat.view,
                                      agent.action, new_path=last is None or not np.array_equal(a, last))
            self._last_actions[end] = a.copy()
            return
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action: expected shape {self.action_space.shape} (a {self.action_type} action), "
                             f"got shape {a.shape}")
        if self.action_type == "force":
            force(a[0:3], a[3:6], agent.action)
            return
        normal = a[3:6] if np.linalg.norm(a[3:6]) > 1e-9 else agent.normal
        last = self._last_actions.get(end)
        if self.action_type == "hold":
            hold(a[0:3], normal, agent.action)
        elif last is None or not np.array_equal(a, last):  # a new path
            view = seat.view  # the observation the agent was last shown
            target(view, a[0:3], normal, vel=a[6:9], at=float(view["time"]) + float(a[9]), out=agent.action)
        self._last_actions[end] = a.copy()

    def play_period(self) -> tuple[list[float], bool, list[bool]]:
        """One control period of the match, stopped early by a decided rally or (Return-v0) the
        agent's landed return: each end's reward (RETURN_STRIKE a strike, RETURN_LANDED a return
        bouncing on the other court, Rally-v0: +1 or -1 the point), whether the rally was decided,
        whether each end's return landed."""
        match, ref = self.match, self.match.referee
        rewards, landed, decided = [0.0, 0.0], [False, False], False
        dense = self.reward == "dense"
        points_before = len(ref.points)
        shots, phase, striker = ref.shots, ref.phase, ref.striker
        potential = self._potentials() if dense else None
        ball_x = float(match.state.ball[0]["pos"][0])
        stop_at = int(match.state.world[0]["tick"]) + self.every
        while int(match.state.world[0]["tick"]) < stop_at and not decided:
            self._advance(stop_at)
            if ref.shots > shots:
                rewards[ref.striker] += RETURN_STRIKE
            if dense:
                x = float(match.state.ball[0]["pos"][0])
                if ref.shots > 0 and (x > 0.0 >= ball_x if ref.striker == 0 else x < 0.0 <= ball_x):
                    rewards[ref.striker] += NET_CLEAR  # the striker's shot crossed into the other half
                ball_x = x
            if len(ref.points) > points_before:  # the rally was decided (the next one is tossed already)
                decided = True
                winner = ref.points[-1].winner
                if (self.task == "rally" or dense) and winner >= 0:
                    rewards[winner] += 1.0
                    rewards[1 - winner] -= 1.0
            elif ref.phase == Phase.BOUNCED and not (phase == Phase.BOUNCED and striker == ref.striker):
                rewards[ref.striker] += RETURN_LANDED  # the striker's return bounced on the other court
                landed[ref.striker] = True
                if self.task == "return" and ref.striker == self.player:
                    break
            shots, phase, striker = ref.shots, ref.phase, ref.striker
        if dense and not decided:
            after = self._potentials()
            for end in (0, 1):
                rewards[end] += after[end] - potential[end]
        return rewards, decided, landed

    def _potentials(self) -> list[float]:
        """Each end's shaping potential: -APPROACH times its bat's distance to the ball while it is
        to strike next, else 0."""
        match = self.match
        key = decision_key(match.rally_record)
        ball = match.state.ball[0]["pos"]
        return [-APPROACH * distance(match.state.bats[end]["pos"], ball) if key[2] == end else 0.0 for end in (0, 1)]

    def _advance(self, target: int | None = None) -> None:
        """Match.tick to the next control tick (or `target`), keeping the episode's frames and events."""
        match = self.match
        tick = int(match.state.world[0]["tick"])
        limit = (tick // self.every + 1) * self.every if target is None else target
        match.tick(min(limit - tick, FRAME_EVERY - tick % FRAME_EVERY))
        if match.n_events:
            self.events.extend(match.events[: match.n_events].copy())
        if int(match.state.world[0]["tick"]) % FRAME_EVERY == 0:
            self._keep_frame()

    def _keep_frame(self) -> None:
        if not self.record:
            return
        record = np.zeros(1, physics_snapshot_dtype(len(self.match.scene.bats)))
        self.match.save(record)
        self.frames.append(record[0])

    def observation(self, end: int | None = None) -> np.ndarray:
        """The observation vector of the agent at `end` (None: the agent's) of the state now (the
        one its next decision is shown)."""
        match = self.match
        state = match.state
        world = state.world[0]
        floats = match.ais.bat_floats(state.bats)
        seat = self.seats[self.player if end is None else end]
        view = seat.observe(int(world["tick"]), float(world["time"]), state.ball_flat, floats,
                            match.rally_record, decision_key(match.rally_record))
        if self.version == 1:
            return agent_frame.observe(view, seat.player, self._obs).copy()
        return flatten(view, self._obs).copy()

    # --- pictures and replays -----------------------------------------------------------------
    def render(self):
        if self.render_mode != "rgb_array" or self.match is None:
            return None
        frames = np.array(self.frames)
        events = np.array(self.events, CONTACT_DTYPE) if self.events else np.zeros(0, CONTACT_DTYPE)
        return render.rgb(frames, events, f"pingpong/{self.task}: agent at {'AB'[self.player]} against "
                                          f"{self.opponent}, step {self.steps}")

    def write_replay(self, path) -> None:
        """The episode so far as a replay file (`pingpong replay FILE --html PAGE` plays it in a browser)."""
        match = self.match
        points = match.referee.points
        replay_file.write(path, scene_name=match.scene.name, scene_text=scene_toml(match.scene), seed=self.seed_of_match,
                          dt=match.model.dt, frame_every=FRAME_EVERY, frames=np.array(self.frames),
                          events=np.array(self.events, CONTACT_DTYPE) if self.events else np.zeros(0, CONTACT_DTYPE),
                          points=np.array([point_row(p, 0) for p in points]) if points else
                          np.zeros(0, POINT_DTYPE),
                          summary={"task": self.task, "opponent": self.opponent, "agent": "ab"[self.player]})


for _task, _name in (("return", "pingpong/Return"), ("rally", "pingpong/Rally")):
    gymnasium.register(f"{_name}-v0", entry_point=f"{__name__}:PingPongEnv", kwargs={"task": _task},
                       max_episode_steps=None, vector_entry_point="engine.learning.vector_env:PingPongVectorEnv")
    gymnasium.register(f"{_name}-v1", entry_point=f"{__name__}:PingPongEnv", kwargs={"task": _task, "version": 1},
                       max_episode_steps=MAX_EPISODE_STEPS[_task],
                       vector_entry_point="engine.learning.vector_env:PingPongVectorEnv")
