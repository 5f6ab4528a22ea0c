"""Serve and attack: a toss-and-drive service, then drives at the ball where it crosses the hitting line.

The flight is predicted as free fall (no drag, no spin): near enough a few tenths of a second
ahead, which is all a drive needs once the ball has bounced on the bot's court. Each stroke is
planned once (engine.play.bot.target) and returned until it is played, so the arm tracks one path.
"""
import numpy as np

from engine.play.bot import Bot, hold, target
from engine.play.rules import Phase

GRAVITY = 9.81  # m/s^2
HIT_X = 1.5  # m from the centre: where the bat meets the ball, behind the end line (1.37 m)


class Attack(Bot):
    pace = 2.5  # m/s, the bat's speed through the ball towards the net
    lift = 1.5  # m/s, its upward speed at impact
    tilt = 0.4  # the face's upward tilt (normal's z over its x)
    serve_pace = 4.5  # m/s, the bat's speed through the tossed ball
    serve_tilt = -0.1  # the face's tilt at the service (down: the ball must bounce on the own court first)

    def setup(self, end, scene):
        self.ready = np.array([self.end_sign * 1.75, 0.0, 0.15])
        self.stroke = None  # the action of the stroke being played, and the rally key it is for
        self.stroke_key = None

    def act(self, obs):
        key = (int(obs["rally"]), int(obs["shots"]))
        if self.stroke is not None and self.stroke_key == key and obs["time"] < self.stroke_end:
            return self.stroke  # the path planned for this ball: keep playing it
        self.stroke = None
        ball = obs["ball"]
        pos, vel = ball["pos"], ball["vel"]
        mine = int(obs["to_strike"]) == self.player
        phase = int(obs["phase"])
        if mine and phase == Phase.WAITING_SERVE and vel[2] < 0 and pos[2] < 0.35:
            return self._plan(obs, key, pos, vel, (-self.end_sign * self.serve_pace, 0.0, 0.0), self.serve_tilt, 0.16)
        if mine and phase == Phase.BOUNCED and vel[0] * self.end_sign > 0.5:
            return self._plan(obs, key, pos, vel, (-self.end_sign * self.pace, 0.0, self.lift), self.tilt, None)
        if mine and phase == Phase.WAITING_SERVE:  # the toss is going up: wait behind the ball
            return hold((pos[0] + self.end_sign * 0.15, pos[1], 0.16), self.normal)
        return hold(self.ready, self.normal)

    def _plan(self, obs, key, pos, vel, bat_vel, tilt, hit_z):
        """A path meeting the ball where it crosses x = hit line (or comes down to hit_z), the bat
        moving at bat_vel there, then back to the ready pose."""
        if hit_z is None:
            x_hit = self.end_sign * HIT_X
            t = (x_hit - pos[0]) / vel[0]
        else:  # a service: where the falling toss passes hit_z
            x_hit = pos[0]
            t = (vel[2] + np.sqrt(max(vel[2] ** 2 + 2 * GRAVITY * (pos[2] - hit_z), 0.0))) / GRAVITY
        if not 0.03 < t < 0.8:
            return hold(self.ready, self.normal)
        hit = (x_hit, pos[1] + vel[1] * t, max(pos[2] + vel[2] * t - 0.5 * GRAVITY * t * t, 0.05))
        now = float(obs["time"])
        face = self.normal + (0.0, 0.0, tilt)
        self.stroke = target(obs, hit, face, vel=bat_vel, at=now + t, then=self.ready)
        self.stroke_key, self.stroke_end = key, now + t + 0.1
        return self.stroke
