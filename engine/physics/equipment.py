"""Equipment and environment constants: ITTF rules and cited measurements, SI units."""

# ITTF Handbook, rule 2.1 (the table): 2.74 m long, 1.525 m wide, surface 76 cm above the floor.
TABLE_LENGTH = 2.74
TABLE_WIDTH = 1.525
TABLE_HEIGHT = 0.76
# The rules fix no top thickness; 25 mm is the common competition top (it only shapes the edge).
TABLE_THICKNESS = 0.025

# ITTF rule 2.2 (the net assembly): top 15.25 cm above the surface, ends 15.25 cm outside the side lines.
NET_HEIGHT = 0.1525
NET_OVERHANG = 0.1525
NET_HALF_WIDTH = TABLE_WIDTH / 2 + NET_OVERHANG  # 0.915 m
# A rigid net is modelled as a thin slab; real nets are a few mm of cord mesh.
NET_THICKNESS = 0.004

# ITTF rule 2.3 (the ball): 40 mm diameter, 2.7 g; a thin spherical shell, so I = 2/3 m r^2.
BALL_RADIUS = 0.020
BALL_MASS = 0.0027
BALL_INERTIA_FACTOR = 2.0 / 3.0
# m/s: the fastest ball a scene may start with (engine/physics/scene.py), about twice the fastest smashes
# played; the cloth net's watch boxes (engine/physics/world.py) and the stability suite assume no faster.
BALL_SPEED_MAX = 60.0

# The rules (2.4) fix no blade size; 150 x 158 mm is the common blade, so a disc of 7.5 cm radius.
# Rule 2.4.4: each covering is at most 4.0 mm thick; with a ~6 mm blade the bat is ~14 mm thick.
BAT_RADIUS = 0.075
BAT_HALF_THICKNESS = 0.007
# A blade with two rubbers weighs 160-200 g; the arm holds its weight (see engine/physics/bat.py).
BAT_MASS = 0.18

GRAVITY = 9.81  # m/s^2, standard gravity rounded as in the ITTF bounce rule's context
AIR_DENSITY = 1.20  # kg/m^3, dry air at 20 degC and sea level

# Drag: flight experiments with ITTF-approved 40 mm balls (Nittaku 3-Star Premium) measured
# C_D between about 0.4 and 0.5 over 3e4 < Re < 9e4 ("Lift crisis of a spinning table tennis ball",
# Eur. J. Phys., 2019); 0.45 is the middle of that band.
DRAG_COEFFICIENT = 0.45
# Magnus: F = 1/2 rho A r C_M (omega x v), i.e. a lift coefficient C_L = C_M * S with spin
# parameter S = r|omega|/|v|. The same flight experiments give C_L ~ 0.2-0.3 for 0.3 < S < 0.5
# away from the lift-crisis valley, hence C_M = 0.6.
MAGNUS_COEFFICIENT = 0.6

# Contact: Coulomb friction with a rolling/sliding switch for a thin shell, after Nakashima,
# Ogawa, Kobayashi, Hayakawa, "Modeling of rebound phenomenon of a rigid ball with friction and
# elastic effects", Proc. American Control Conference 2010, pp. 1410-1415. Their fitted friction
# coefficients are mu = 0.25 for the table and a much higher one for inverted rubber.
TABLE_FRICTION = 0.25
BAT_FRICTION = 0.9
# Restitution of ball on table, tuned so that a ball dropped from 30 cm (bottom of the ball)
# bounces back to 23 cm with drag (ITTF rule 2.1.3); tests/engine/test_drop.py holds it to +-1 cm.
# Without drag e = sqrt(23/30) = 0.876; drag (C_D above) costs about 3 cm more on the way down and
# up. 0.905 was found by bisection on the engine itself (rk4, dt = 0.1 ms: first apex 22.99 cm).
TABLE_RESTITUTION = 0.905
# Apparent restitution of the bat (blade, rubber and the player's hand recoiling): measured
# normal-impact values for inverted rubbers lie around 0.8-0.9 (Rinaldi et al., "Table tennis
# ball impacting racket polymeric coatings", Appl. Sci. 9(1):158, 2019).
BAT_RESTITUTION = 0.85
# Floor (wood sports floor) and net cord: only the shape of a dead ball matters there.
FLOOR_RESTITUTION = 0.80
FLOOR_FRICTION = 0.40
NET_RESTITUTION = 0.20
NET_FRICTION = 0.30

# Below this approach speed an impact does not bounce and the ball rests on the surface: a
# bounce from 1 cm/s rises 5 um, far below anything that matters, and stopping there ends the
# infinite bounce sequence (Zeno) that exact restitution would give.
REST_SPEED = 0.01
