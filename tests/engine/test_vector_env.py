"""The native vector environment: Gymnasium's VectorEnv API, NEXT_STEP autoreset, and each table's
episodes bit for bit those of a single environment with the same seed."""
import gymnasium
import numpy as np
import pytest

import engine.learning.env  # noqa: F401 - registers the ids and their vector entry point
from engine.learning.batch import OPP_TAKEN, TableBatch
from engine.learning.batch_net import NET_OWED
from engine.learning.env import FRAME_EVERY, PingPongEnv
from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.world import NET_RUN_TICKS
from engine.learning.vector_env import PingPongVectorEnv
from net_kernel import NetSim
from net_kernel.sim import compile_kernels

KWARGS = {"opponent": "novice", "max_seconds": 0.12}  # 12 control periods an episode: several autoresets


def _actions(space, steps: int, seed: int) -> np.ndarray:
    space.seed(seed)
    return np.array([space.sample() for _ in range(steps)])


def _single_next_step(seed: int, actions: np.ndarray, kwargs: dict):
    """One PingPongEnv reset with `seed`, stepped with `actions` under Gymnasium's documented
    NEXT_STEP autoreset: after an ended episode the next step resets (its action ignored) and
    returns the reset's observation, reward 0, neither terminated nor truncated."""
    env = PingPongEnv(**kwargs)
    obs, _ = env.reset(seed=seed)
    rows, ended = [(obs, 0.0, False, False)], False
    for action in actions:
        if ended:
            obs, _ = env.reset()
            rows.append((obs, 0.0, False, False))
            ended = False
        else:
            obs, reward, terminated, truncated, _ = env.step(action)
            rows.append((obs, reward, terminated, truncated))
            ended = terminated or truncated
    return rows


def _vector_rows(vector, seed, actions):
    obs, _ = vector.reset(seed=seed)
    rows = [(obs, np.zeros(vector.num_envs), np.zeros(vector.num_envs, bool), np.zeros(vector.num_envs, bool))]
    for action in actions:
        obs, reward, terminated, truncated, _ = vector.step(action)
        rows.append((obs, reward, terminated, truncated))
    return rows


@pytest.mark.parametrize("task", ["return", "rally"])
def test_each_table_is_the_single_environment_with_its_seed_bit_for_bit(task):
    n, steps = 3, 40
    vector = gymnasium.make_vec(f"pingpong/{task.capitalize()}-v0", num_envs=n,
                                vectorization_mode="vector_entry_point", **KWARGS)
    assert isinstance(vector, PingPongVectorEnv)
    assert vector.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    actions = _actions(vector.action_space, steps, seed=4)
    rows = _vector_rows(vector, 30, actions)  # an int seed: table k gets 30 + k
    assert sum(int(r[3].sum() + r[2].sum()) for r in rows) >= n * 2  # every table ended episodes and went on
    for k in range(n):
        single = _single_next_step(30 + k, actions[:, k], {"task": task, **KWARGS})
        for got, expected in zip(rows, single, strict=True):
            assert got[0][k].tobytes() == expected[0].tobytes()
            assert (float(got[1][k]), bool(got[2][k]), bool(got[3][k])) == expected[1:]


def test_the_same_steps_as_gymnasiums_sync_vector_env():
    n, steps = 2, 30
    native = PingPongVectorEnv(n, **KWARGS)
    sync = gymnasium.vector.SyncVectorEnv([lambda: PingPongEnv(**KWARGS)] * n)
    assert sync.metadata["autoreset_mode"] == native.metadata["autoreset_mode"]
    actions = _actions(native.action_space, steps, seed=8)
    for ours, theirs in zip(_vector_rows(native, [5, 9], actions), _vector_rows(sync, [5, 9], actions), strict=True):
        for a, b in zip(ours, theirs, strict=True):
            assert np.asarray(a).tobytes() == np.asarray(b).tobytes()


def test_a_reset_mask_resets_only_the_masked_tables():
    vector = PingPongVectorEnv(3, **KWARGS)
    first, _ = vector.reset(seed=[1, 2, 3])
    actions = np.stack([vector.single_action_space.sample() * 0.0 + [1.6, 0.0, 0.2, -1.0, 0.0, 0.2]] * 3)
    moved, *_ = vector.step(actions)
    obs, infos = vector.reset(seed=[1, 7, 3], options={"reset_mask": np.array([True, False, False])})
    assert obs[0].tobytes() == first[0].tobytes()  # table 0 again from seed 1
    assert obs[1:].tobytes() == moved[1:].tobytes()  # the others untouched
    assert infos["_drive"].tolist() == [True, False, False]


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="num_envs"):
        PingPongVectorEnv(0)
    vector = PingPongVectorEnv(2, **KWARGS)
    with pytest.raises(ValueError, match="one seed per table"):
        vector.reset(seed=[1, 2, 3])
    vector.reset(seed=0)
    with pytest.raises(ValueError, match="actions: shape"):
        vector.step(np.zeros((3, 6)))
    with pytest.raises(ValueError, match="reset_mask"):
        vector.reset(options={"reset_mask": np.zeros(2, bool)})


@pytest.mark.parametrize("kwargs", [
    {"task": "return", "reward": "sparse"},
    {"task": "rally", "reward": "dense", "player": 0},
    {"task": "return", "reward": "dense", "ball_speed": (6.0, 12.0), "ball_spin": (-200.0, 200.0)},
])
def test_the_batched_step_is_the_single_environment_bit_for_bit(kwargs):
    """Version 1, hold actions: every table stepped in one compiled call (the opponent's decisions
    in Python), each equal to a single environment with its seed."""
    kwargs = {"opponent": "novice", "version": 1, "max_seconds": 1.0, **kwargs}
    n, steps = 2, 260
    vector = PingPongVectorEnv(n, **kwargs)
    assert vector.batched
    actions = np.random.default_rng(3).uniform(-1.2, 1.2, size=(steps, n, 6))  # beyond [-1, 1]: clipped
    rows = _vector_rows(vector, 50, actions)
    assert sum(int(r[2].sum() + r[3].sum()) for r in rows) >= n * 2  # episodes ended and began again
    for k in range(n):
        single = _single_next_step(50 + k, actions[:, k], kwargs)
        for got, expected in zip(rows, single, strict=True):
            assert got[0][k].tobytes() == expected[0].tobytes()
            assert (float(got[1][k]), bool(got[2][k]), bool(got[3][k])) == expected[1:]


def test_the_batched_cloth_net_owes_its_ticks_and_gives_the_single_environments_bits(monkeypatch):
    """With the cloth net the batch steps the ball's ticks out of the net's reach in its compiled
    call and the net's own ticks (those and the ones near the ball) in Python, only when the ball
    comes near again: a struck net, still ringing, is stepped over the ticks it owes then. Each
    table is the single environment with its seed, bit for bit, and so is the net the ball meets
    (its knots at every tick it might touch the ball: a sleeping net's sweep, an awake net's tick
    with the ball near)."""
    assert FRAME_EVERY < NET_RUN_TICKS  # a batch call ends where a run near the net does (batch_net)
    kwargs = {"opponent": "novice", "version": 1, "max_seconds": 3.0, "net": "cloth", "task": "rally"}
    n, steps = 3, 500
    met, paid, table = {}, [], [None]
    touches, ball_tick, step_net = NetSim.touches, NetSim._ball_tick, TableBatch._step_net

    def seen(net):
        if table[0] != "warming":
            met.setdefault(table[0], []).append((net.sleeping, net.in_tail, net.knot_pos.tobytes(),
                                                 net.knot_vel.tobytes()))

    def warming(*args):  # an environment's first reset loads the net's kernels on a throwaway net
        table[0], before = "warming", table[0]
        compile_kernels(*args)
        table[0] = before

    def seen_touches(net, *args):
        seen(net)
        return touches(net, *args)

    def seen_ball_tick(net, *args):
        seen(net)
        return ball_tick(net, *args)

    def seen_step_net(batch, k):
        if batch.net_ints[k, NET_OWED] > 0 and not batch.envs[k].match.state.net_sim.sleeping:
            paid.append(k)
        table[0] = k
        step_net(batch, k)

    monkeypatch.setattr(engine.learning.env, "compile_kernels", warming)
    monkeypatch.setattr(NetSim, "touches", seen_touches)
    monkeypatch.setattr(NetSim, "_ball_tick", seen_ball_tick)
    monkeypatch.setattr(TableBatch, "_step_net", seen_step_net)
    vector = PingPongVectorEnv(n, **kwargs)
    assert vector.batched
    actions = np.random.default_rng(1).uniform(-1.2, 1.2, size=(steps, n, 6))
    rows = _vector_rows(vector, 70, actions)
    assert len(paid) >= 3  # ringing nets stepped over the ticks they owed: the path this test is for
    assert sum(len(v) for v in met.values()) >= 50  # balls met nets in play: what this test compares
    for k in range(n):
        table[0] = ("single", k)
        single = _single_next_step(70 + k, actions[:, k], kwargs)
        for got, expected in zip(rows, single, strict=True):
            assert got[0][k].tobytes() == expected[0].tobytes()
            assert (float(got[1][k]), bool(got[2][k]), bool(got[3][k])) == expected[1:]
        assert met.get(k) == met.get(("single", k))


def test_a_batched_lead_in_whose_match_ended_first_leads_in_anew_as_the_single_environment(monkeypatch):
    """A drive's lead-in whose match is over before the opponent drove is played again in the
    episode's next match (its next seed), in the batch as in PingPongEnv.reset."""
    begin, next_match = PingPongEnv.begin_episode, PingPongEnv.next_match
    episodes, matches = [], []

    def begin_ended_first(env, seed=None):
        env.end_first = True
        episodes.append(seed)
        return begin(env, seed)

    def next_match_ended_first(env):
        next_match(env)
        matches.append(env.seed_of_match)
        if env.end_first and env.agent.stand_in is not None:  # a drive's first match: the opponent won it
            env.end_first = False
            record = np.zeros(1, physics_snapshot_dtype(len(env.match.scene.bats)))
            env.match.save(record)
            record[0]["rally"]["winner"] = 1 - env.player
            env.match.restore(record[0], [])

    monkeypatch.setattr(PingPongEnv, "begin_episode", begin_ended_first)
    monkeypatch.setattr(PingPongEnv, "next_match", next_match_ended_first)
    kwargs = {"opponent": "novice", "version": 1, "max_seconds": 0.3}
    n, steps = 2, 60
    vector = PingPongVectorEnv(n, **kwargs)
    actions = np.random.default_rng(5).uniform(-1.0, 1.0, size=(steps, n, 6))
    rows = _vector_rows(vector, 70, actions)
    batched = (len(episodes), sorted(matches))
    assert batched[1] and len(matches) - len(episodes) >= 2  # lead-ins played anew: the path this test is for
    episodes.clear()
    matches.clear()
    for k in range(n):
        single = _single_next_step(70 + k, actions[:, k], kwargs)
        for got, expected in zip(rows, single, strict=True):
            assert got[0][k].tobytes() == expected[0].tobytes()
            assert (float(got[1][k]), bool(got[2][k]), bool(got[3][k])) == expected[1:]
    assert (len(episodes), sorted(matches)) == batched


def test_the_batched_step_names_a_non_finite_action():
    vector = PingPongVectorEnv(2, opponent="novice", version=1)
    vector.reset(seed=0)
    actions = np.zeros((2, 6))
    actions[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"entries \[2\] are not finite"):
        vector.step(actions)


def test_tables_share_their_compiled_scenes_and_refuse_another_scene():
    vector = PingPongVectorEnv(3, opponent="novice", version=1)
    vector.reset(seed=0)
    first, *others = vector.envs
    assert all(env._compiled is first._compiled for env in others)
    with pytest.raises(ValueError, match="another scene, opponent or end"):
        PingPongEnv(opponent="pro", version=1).share_scenes(first)


def test_the_opponents_quiet_decisions_are_taken_compiled_and_handed_back_to_its_ai():
    """The decisions of the opponent that need no Python (the ball changed hands, its plan ran
    out: engine.learning.batch._quiet_decision) are taken in the compiled call; handed back
    (TableBatch._sync), its seat and BatAI are those of a single environment's at the same step."""
    kwargs = {"opponent": "novice", "version": 1}
    vector = PingPongVectorEnv(2, **kwargs)
    vector.reset(seed=5)
    single = PingPongEnv(**kwargs)
    single.reset(seed=5)
    action = np.zeros(6)
    batch, opp, taken = vector.batch, 1 - single.player, 0
    for _ in range(400):
        taken += int(batch.opp_ai[0, OPP_TAKEN])
        batch._sync(0)
        mine, theirs = vector.envs[0].match.ais[opp], single.match.ais[opp]
        assert (mine.key, mine.decisions) == (theirs.key, theirs.decisions)
        assert (mine.bot.ai.turn_key, mine.bot.ai.turn_seen_at, mine.bot.ai.plan is None) == \
               (theirs.bot.ai.turn_key, theirs.bot.ai.turn_seen_at, theirs.bot.ai.plan is None)
        assert mine.ctl.tobytes() == theirs.ctl.tobytes()
        _, _, terminated, truncated, _ = single.step(action)
        vector.step(np.stack([action, action]))
        if terminated or truncated:
            break
    assert taken > 0  # some were taken in the compiled call (counted until handed back)
