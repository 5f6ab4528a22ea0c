"""The learning environments: Gymnasium, vector and PettingZoo environments, the agent's frame and the ball machine."""
