"""The match: its rules, the arm, the players, the match loop and the engine's own AI (ai/)."""
