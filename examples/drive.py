"""Drive: predict the ball with the table's own physics, then place a fast, safe drive deep.

- Prediction: the flight is integrated with gravity, drag and Magnus lift, the bounce on the table
  with restitution and friction (engine.physics.equipment's constants, with their sources, and
  engine.physics.contact.impact, the engine's own impact model).
- Return: struck at the top of its bounce on the own court, aimed `depth` inside the other end line
  at the fastest pace whose arc clears the net by `net_margin`; the launch is solved on the
  predicted flight, the bat face and velocity giving it on the rubber's impact model.
- The bat follows one Hermite path to the ball, planned once per ball (again if the ball leaves
  the predicted path, e.g. off the net), and waits beside the line of the toss, not to knock it.
- Service: the falling toss is pushed down to bounce on the own court, then deep on the other.
"""
import math

import numpy as np

from engine.physics import contact
from engine.physics import equipment as eq
from engine.play.bot import Bot, hold, target
from engine.play.rules import Phase

# The ball, the air, the table and the rubber as the engine has them (engine/physics/equipment.py cites
# each); the forces as engine/physics/forces.py writes them.
G, R, M = eq.GRAVITY, eq.BALL_RADIUS, eq.BALL_MASS
I = eq.BALL_INERTIA_FACTOR * M * R**2
K_DRAG = 0.5 * eq.AIR_DENSITY * eq.DRAG_COEFFICIENT * math.pi * R**2 / M  # a = -K_DRAG |v| v
K_MAGNUS = 0.5 * eq.AIR_DENSITY * math.pi * R**2 * R * eq.MAGNUS_COEFFICIENT / M  # a = K_MAGNUS (w x v)
TABLE_E, TABLE_MU, BAT_E, BAT_MU = eq.TABLE_RESTITUTION, eq.TABLE_FRICTION, eq.BAT_RESTITUTION, eq.BAT_FRICTION
HALF_L, HALF_W, NET_TOP, BAT_HALF = eq.TABLE_LENGTH / 2, eq.TABLE_WIDTH / 2, eq.NET_HEIGHT, eq.BAT_HALF_THICKNESS
DT = 0.002  # s, the prediction's step


def impact(v, w, n, body_v, e, mu):
    """Velocity and spin after hitting a body moving at body_v, normal n (the engine's own model)."""
    out_v, out_w = np.empty(3), np.empty(3)
    contact.impact(np.asarray(v, float), np.asarray(w, float), np.asarray(n, float), np.asarray(body_v, float),
                   R, M, I, e, mu, out_v, out_w)
    return out_v, out_w


def fly(p, v, w, t_max=1.5, bounce=True, dt=DT):
    """Rows (t, pos, vel, spin) every dt s of the free ball (semi-implicit Euler on plain floats, for
    speed). It bounces on the table if `bounce`, else stops where it comes down to table height."""
    (x, y, z), (vx, vy, vz), (wx, wy, wz) = p, v, w
    rows, t = [], 0.0
    while t < t_max and z > -0.5:
        s = math.sqrt(vx * vx + vy * vy + vz * vz)
        ax = -K_DRAG * s * vx + K_MAGNUS * (wy * vz - wz * vy)
        ay = -K_DRAG * s * vy + K_MAGNUS * (wz * vx - wx * vz)
        az = -K_DRAG * s * vz + K_MAGNUS * (wx * vy - wy * vx) - G
        vx, vy, vz = vx + ax * dt, vy + ay * dt, vz + az * dt
        x, y, z, t = x + vx * dt, y + vy * dt, z + vz * dt, t + dt
        if z < R and vz < 0 and not bounce:  # back to where it came down through table height
            s = (z - R) / (vz * dt)
            rows.append((t - s * dt, x - s * vx * dt, y - s * vy * dt, R, vx, vy, vz, wx, wy, wz))
            break
        if z < R and vz < 0 and abs(x) < HALF_L and abs(y) < HALF_W:
            (vx, vy, vz), (wx, wy, wz) = impact(np.array([vx, vy, vz]), np.array([wx, wy, wz]),
                                                np.array([0.0, 0.0, 1.0]), np.zeros(3), TABLE_E, TABLE_MU)
            z = 2 * R - z
        rows.append((t, x, y, z, vx, vy, vz, wx, wy, wz))
    return np.array(rows)


def shoot(p, w, aim, pace):
    """Launch velocity from p, `pace` m/s horizontally, whose flight (spin w) comes down on aim (x, y):
    the secant method on its vertical speed, from the drag-free guess."""
    d = np.asarray(aim) - p[:2]
    dist = np.hypot(*d)
    u = d / dist

    def miss(vz):  # how far beyond the aim it comes down
        v = np.array([*(pace * u), vz])
        return (fly(p, v, w, bounce=False, dt=2 * DT)[-1, 1:3] - p[:2]) @ u - dist, v

    vz0 = (R - p[2]) * pace / dist + G * dist / pace / 2
    vz1, e0 = vz0 + 0.5, miss(vz0)[0]
    for _ in range(6):
        e1, v = miss(vz1)
        if abs(e1) < 0.01 or e1 == e0:
            break
        vz0, vz1, e0 = vz1, vz1 - e1 * (vz1 - vz0) / (e1 - e0), e1
    return v


def stroke(p, v_in, w_in, aim, pace):
    """Face normal and bat velocity sending the ball (v_in, w_in) at p to aim: the impulse along the
    normal (rubber restitution), corrected for the rubber's friction by fixed-point iteration, and
    the shot solved again with the spin that stroke gives."""
    w_out = np.zeros(3)
    for _ in range(2):
        v_out = shoot(p, w_out, aim, pace)
        change = v_out - v_in
        for _ in range(10):
            n = change / np.linalg.norm(change)
            bat = (v_in @ n + np.linalg.norm(change) / (1 + BAT_E)) * n
            got_v, w_out = impact(v_in, w_in, n, bat, BAT_E, BAT_MU)
            change += v_out - got_v
    return n, bat


class Drive(Bot):
    depth = 0.35  # m inside the other end line: where a return comes down
    net_margin = 0.07  # m its drag-free arc clears the net by
    max_pace = 11.0  # m/s, the fastest return (horizontal)
    near = 0.8  # m in front of the end line: a ball nearer the net is let come on, if it will
    swing = 0.10  # s, the shortest stroke, from when it takes effect to the hit
    serve_z, serve_bounce, serve_pace = 0.25, 1.0, 6.5  # m toss height, m from the net, m/s

    def setup(self, end, scene):
        # Beside the toss's line (10 cm behind the end line, y = 0: engine/play/match.py's toss).
        self.ready = np.array([self.end_sign * 1.75, 0.3, 0.2])
        self.plan, self.key, self.path = None, None, None
        # The engine's impact kernel compiles (or loads) here, not in a timed decision.
        impact(np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 1.0]), np.zeros(3), TABLE_E, TABLE_MU)

    def act(self, obs):
        key = (int(obs["rally"]), int(obs["shots"]))
        ball, now = obs["ball"], float(obs["time"])
        if self.plan is not None and key == self.key and now < self.t_hit + 0.05:
            # Keep playing the stroke planned for this ball, unless the ball left the predicted
            # path by 2 cm while there is still time to plan again.
            k = min(int(round((now - self.t0) / DT)) - 1, len(self.path) - 1)
            if self.t_hit - now < self.swing + self.latency or np.linalg.norm(self.path[k, 1:4] - ball["pos"]) < 0.02:
                return self.plan
        self.plan = None
        mine = int(obs["to_strike"]) == self.player
        if mine and int(obs["phase"]) == Phase.WAITING_SERVE:
            return self._serve(obs, key)
        if mine and ball["vel"][0] * self.end_sign > 0 and ball["pos"][2] > 0:
            return self._return(obs, key) or self._rest(obs)
        return self._rest(obs)

    def _rest(self, obs):
        """Hold the ready pose; from in front of the toss's line, step aside to its y first."""
        own = obs["own"]["pos"]
        if self.end_sign * own[0] < HALF_L + 0.15 and abs(own[1] - self.ready[1]) > 0.1:
            return hold((own[0], *self.ready[1:]), self.normal)
        return hold(self.ready, self.normal)

    def _serve(self, obs, key):
        """Strike the toss at serve_z on its way down, to bounce serve_bounce m from the net first."""
        ball = obs["ball"]
        toss = fly(ball["pos"], ball["vel"], ball["spin"], t_max=1.0)
        k = np.flatnonzero((toss[:, 6] < 0) & (toss[:, 3] < self.serve_z) & (toss[:, 0] > self.latency + self.swing))
        if len(k) == 0 or self.end_sign * obs["own"]["pos"][0] < HALF_L + 0.15:
            return self._rest(obs)
        row = toss[k[0]]
        n, bat_v = stroke(row[1:4], row[4:7], row[7:10], (self.end_sign * self.serve_bounce, 0.0), self.serve_pace)
        return self._swing(obs, key, row, n, bat_v, toss)

    def _return(self, obs, key):
        """The stroke for the coming ball; None if it will not bounce on this court (let it go)."""
        found = self._meeting(obs)
        if found is None:
            return None
        row, path = found
        n, bat_v = self._stroke(row)
        return self._swing(obs, key, row, n, bat_v, path)

    def _meeting(self, obs):
        """Where to meet the coming ball: (the row of its predicted path, the path), or None if it
        will not bounce on this court."""
        ball = obs["ball"]
        path = fly(ball["pos"], ball["vel"], ball["spin"])
        sx = self.end_sign * path[:, 1]
        bounces = np.flatnonzero((path[1:, 6] > 0) & (path[:-1, 6] < 0) & (sx[1:] > 0)) + 1
        if len(bounces) == 0:
            return None
        after = slice(bounces[0], bounces[1] if len(bounces) > 1 else len(path))  # before a 2nd bounce
        t, x, z, vz = path[after, 0], sx[after], path[after, 3], path[after, 6]
        ok = (t > self.latency + self.swing) & (z > 0.05) & (x > 0.3)
        far = ok & (x > HALF_L - self.near)
        # At the top of the bounce or far behind the end line; else as soon as it is far enough
        # from the net; else (a short ball) at the top of its bounce over the table.
        for mask in (far & ((vz <= 0) | (x > HALF_L + 0.3)), far, ok & (vz <= 0)):
            if mask.any():
                break
        if not mask.any():
            return None
        return path[after][np.flatnonzero(mask)[0]], path

    def _stroke(self, row):
        """Face normal and bat velocity for the ball at `row` of its path: a drive `depth` inside
        the other end line, at the fastest pace that clears the net by `net_margin`."""
        p = row[1:4]
        aim = np.array([-self.end_sign * (HALF_L - self.depth), 0.0])
        # The fastest pace whose drag-free arc from p down to aim passes net_margin over the net:
        # f of the way along, that arc is g f (1 - f) dist^2 / (2 pace^2) above the straight line.
        f, dist = abs(p[0]) / abs(p[0] - aim[0]), np.hypot(*(aim - p[:2]))
        rise = NET_TOP + R + self.net_margin - (p[2] + f * (R - p[2]))
        pace = min(self.max_pace, math.sqrt(G * f * (1 - f) * dist**2 / (2 * rise))) if rise > 0 else self.max_pace
        return stroke(p, row[4:7], row[7:10], aim, pace)

    def _swing(self, obs, key, row, normal, bat_v, path):
        """One Hermite path from the bat's state to meet the ball at `row` of its path, face `normal`,
        moving at `bat_v`; kept while the ball follows `path`."""
        now = float(obs["time"])
        centre = row[1:4] - (R + BAT_HALF) * normal
        self.plan = target(obs, centre, normal, vel=bat_v, at=now + row[0])
        self.key, self.t_hit, self.path, self.t0 = key, now + row[0], path, now
        return self.plan
