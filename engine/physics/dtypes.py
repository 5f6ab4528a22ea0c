"""Every structured dtype of the simulation state, little-endian and explicit."""
import numpy as np

# The ball's ordinary differential equation state. All fields are '<f8' with no padding, so a
# ball array views as a flat float64 vector `ball.view('<f8')` of 9 numbers: pos, vel, spin.
BALL_DTYPE = np.dtype(
    [
        ("pos", "<f8", (3,)),  # m, centre, world frame
        ("vel", "<f8", (3,)),  # m/s
        ("spin", "<f8", (3,)),  # rad/s, angular velocity, world frame
    ]
)

# A bat is a rigid disc driven only by forces and torques (arm holds its weight).
BAT_DTYPE = np.dtype(
    [
        ("pos", "<f8", (3,)),  # m, centre of the blade
        ("quat", "<f8", (4,)),  # unit quaternion (w, x, y, z): bat frame -> world; bat z = face normal
        ("vel", "<f8", (3,)),  # m/s
        ("ang_vel", "<f8", (3,)),  # rad/s, world frame
        ("force", "<f8", (3,)),  # N, input held over the tick (user or AI)
        ("torque", "<f8", (3,)),  # N m, input held over the tick
    ]
)

# A bat's motion as a player sees it: BAT_DTYPE's first four fields, at the same offsets.
BAT_STATE_DTYPE = np.dtype(
    [
        ("pos", "<f8", (3,)),  # m, centre of the blade
        ("quat", "<f8", (4,)),  # unit quaternion (w, x, y, z): bat frame -> world; bat z = face normal
        ("vel", "<f8", (3,)),  # m/s
        ("ang_vel", "<f8", (3,)),  # rad/s, world frame
    ]
)

# What a player (engine.play.bot.Bot) sees at each of its control ticks, and all it sees: the ball as
# the wire's snapshot shows it, its own bat and the other one, the referee's public state and the
# clock. World frame and SI units like everything else; players are 0 (A, x < 0) and 1 (B).
OBSERVATION_DTYPE = np.dtype(
    [
        ("tick", "<i8"),  # the tick the state is at
        ("time", "<f8"),  # s, simulated
        ("ball", BALL_DTYPE),  # pos m, vel m/s, spin rad/s
        ("own", BAT_STATE_DTYPE),  # the player's bat
        ("other", BAT_STATE_DTYPE),  # the opponent's bat
        ("score", "<i4", (2,)),  # points in the current game, A then B
        ("games_won", "<i4", (2,)),  # A then B
        ("phase", "<i4"),  # engine.play.rules.Phase: 0 waiting for the service ... 5 rally decided
        ("server", "<i4"),  # the player serving this rally
        ("to_strike", "<i4"),  # the player who must strike the ball next, -1 for nobody
        ("shots", "<i4"),  # strikes in this rally, the service included
        ("rally", "<i8"),  # rallies started since the match began
    ]
)

# How many segments an arm target's path holds: backswing, swing, follow-through.
ARM_SEGMENTS = 3

# What a player answers (engine.play.bot): kind ACTION_TARGET, the arm's target (a pose to hold and
# a path of cubic Hermite segments of the bat centre, (t0, t1, p0, v0, p1, v1) with times s
# in the world clock, positions m, velocities m/s), which engine.play.arm's PD law turns into force
# and torque within the arm's limits; or kind ACTION_FORCE, the force and torque themselves,
# each within the arm's limits. The float fields come first, so a record's first ACTION_FLOATS
# bytes view as float64.
ACTION_DTYPE = np.dtype(
    [
        ("force", "<f8", (3,)),  # N, world frame (ACTION_FORCE)
        ("torque", "<f8", (3,)),  # N m (ACTION_FORCE)
        ("hold", "<f8", (3,)),  # m, where the bat stays once the path is over (ACTION_TARGET)
        ("normal", "<f8", (3,)),  # unit, the face normal to turn to (ACTION_TARGET)
        ("segments", "<f8", (ARM_SEGMENTS, 14)),  # t0, t1, p0 (3), v0 (3), p1 (3), v1 (3), in time order
        ("n_segments", "<i4"),  # segments in use, 0 .. ARM_SEGMENTS
        ("kind", "<i4"),  # 0 ACTION_TARGET, 1 ACTION_FORCE
    ]
)

# Scalars of the world, one record per world.
WORLD_DTYPE = np.dtype(
    [
        ("tick", "<i8"),
        ("time", "<f8"),  # s, simulated
        ("ball_support", "<i4"),  # Body id the ball rests or rolls on, 0 = in flight
        ("n_events", "<i4"),  # contact events written during the last tick
        ("events_total", "<i8"),  # contact events since tick 0
        # dopri5's next trial substep (s) and its accepted and rejected substeps: state, not
        # scratch, because the next tick's substeps depend on it (restarts must restore it).
        ("ball_adapt", "<f8", (3,)),
    ]
)

# One impact of the ball on a body.
CONTACT_DTYPE = np.dtype(
    [
        ("tick", "<i8"),
        ("time", "<f8"),  # s, time of impact inside the tick
        ("body", "<i4"),  # engine.physics.geometry.Body id
        ("pos", "<f8", (3,)),  # m, ball centre at impact
        ("normal", "<f8", (3,)),  # unit, from the body towards the ball
        ("vel_in", "<f8", (3,)),
        ("vel_out", "<f8", (3,)),
        ("spin_in", "<f8", (3,)),
        ("spin_out", "<f8", (3,)),
        ("normal_speed", "<f8"),  # m/s, approach speed along the normal relative to the body
    ]
)

# The referee's whole state and the match's rally bookkeeping (engine/play/rules.py, engine/play/match.py),
# so a restarted physics worker resumes a match mid-rally and the AI knows whose ball it is.
RALLY_DTYPE = np.dtype(
    [
        ("rally", "<i8"),  # rallies started since the match began
        ("rally_started", "<f8"),  # s, simulated time of this rally's toss
        ("shots", "<i8"),  # strikes in this rally
        ("phase", "<i4"),  # engine.play.rules.Phase
        ("server", "<i4"),  # player 0 (A) or 1 (B)
        ("striker", "<i4"),
        ("touched_net", "<i4"),
        ("score", "<i4", (2,)),  # points in the current game
        ("games_won", "<i4", (2,)),
        ("game_first_server", "<i4"),
        ("deciding_ends_swapped", "<i4"),
        ("winner", "<i4"),  # -1 while the match is on
        ("points_total", "<i8"),  # entries in the point log (lets included)
    ]
)

# One decided rally, as the point log and the replay file keep it.
POINT_DTYPE = np.dtype(
    [
        ("tick", "<i8"),
        ("game", "<i4"),
        ("server", "<i4"),
        ("winner", "<i4"),  # -1 for a let
        ("reason", "<i4"),  # index into engine.play.rules.REASONS
        ("shots", "<i4"),
        ("score_after", "<i4", (2,)),
    ]
)


def physics_snapshot_dtype(n_bats: int) -> np.dtype:
    """Everything the physics worker owns at one tick, as one record: ball, bats, world, rally."""
    return np.dtype([("ball", BALL_DTYPE), ("bats", BAT_DTYPE, (n_bats,)), ("world", WORLD_DTYPE),
                     ("rally", RALLY_DTYPE)])


def net_snapshot_dtype(n_knots: int) -> np.dtype:
    """The cloth net's whole state at one tick, as one record (the net worker publishes it).

    tick: physics ticks done when this state holds (the net steps tick `tick - 1` to get here);
    sleeping, quiet_ticks: net_kernel.NetSim's sleep state; tail: -1, or the ticks the net's
    linear tail has run (net_kernel/tail.py): then pos, vel and quiet_ticks are the state it
    started from (tick - tail) and the net's state at `tick` is the tail's at that many ticks;
    pos, vel: m, m/s per knot.
    """
    return np.dtype([("tick", "<i8"), ("sleeping", "<i8"), ("quiet_ticks", "<i8"), ("tail", "<i8"),
                     ("pos", "<f8", (n_knots, 3)), ("vel", "<f8", (n_knots, 3))])


def net_show_dtype(n_knots: int) -> np.dtype:
    """The cloth net as clients are shown it, at one tick (the net worker publishes it for a
    gateway): tick, asleep (1: it stays in this shape until it wakes), pos m per knot. In the
    net's linear tail, the tail's knots at that tick."""
    return np.dtype([("tick", "<i8"), ("asleep", "<i8"), ("pos", "<f8", (n_knots, 3))])


def ai_answer_dtype(max_bats: int, ctl_size: int) -> np.dtype:
    """The AIs' answer to one turn, a control tick's state (the AI worker writes it, the physics
    reads it).

    turn: the turn's number (processes.runtime.handoff.TurnQueue), tick: the control tick whose
    state it answers; changed: 1 if a player decided there, 0 if none could decide differently;
    ctl: (max_bats, ctl_size) each AI's plan after it (engine.play.arm's CTL_* layout), in the order of
    the scene's AI bats, which the physics plays from the tick the decision takes effect; fault:
    (max_bats,) per bat, engine.play.bot.FAULTS index of what went wrong with its player's decision
    (0: nothing), fault_text: what, in words; gate_key, gate_due, gate_end: each AI's decision
    gate after it (engine.play.players.Players.gates: its key at its last decision, its wakes in
    s), from which the physics knows whether anybody could decide at its next control ticks.
    """
    return np.dtype([("turn", "<i8"), ("tick", "<i8"), ("changed", "<i8"), ("ctl", "<f8", (max_bats, ctl_size)),
                     ("fault", "<i4", (max_bats,)), ("fault_text", "S240", (max_bats,)),
                     ("gate_key", "<i8", (max_bats, 4)), ("gate_due", "<f8", (max_bats,)),
                     ("gate_end", "<f8", (max_bats,))])
