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
        ("body", "<i4"),  # engine.geometry.Body id
        ("pos", "<f8", (3,)),  # m, ball centre at impact
        ("normal", "<f8", (3,)),  # unit, from the body towards the ball
        ("vel_in", "<f8", (3,)),
        ("vel_out", "<f8", (3,)),
        ("spin_in", "<f8", (3,)),
        ("spin_out", "<f8", (3,)),
        ("normal_speed", "<f8"),  # m/s, approach speed along the normal relative to the body
    ]
)


def physics_snapshot_dtype(n_bats: int) -> np.dtype:
    """Everything the physics worker owns at one tick, as one record: ball, bats, world."""
    return np.dtype([("ball", BALL_DTYPE), ("bats", BAT_DTYPE, (n_bats,)), ("world", WORLD_DTYPE)])
