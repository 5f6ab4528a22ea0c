"""Block it back: wait behind the end line in the ball's line, face tilted up, and let the ball come."""
import numpy as np

from engine.play.bot import Bot, hold


class Block(Bot):
    def act(self, obs):
        y, z = np.clip(obs["ball"]["pos"][1:3], (-0.6, 0.05), (0.6, 0.35))
        return hold((self.end_sign * 1.45, y, z), self.normal + (0.0, 0.0, 0.3))
