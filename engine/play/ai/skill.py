"""How well a bat plays: the Skill record and the SKILLS profiles."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Skill:
    """How well a bat plays. Noise is one standard deviation."""

    reaction_s: float  # delay after the opponent's strike before the AI starts its stroke
    aim_noise_m: float  # error of the landing point it aims at
    face_noise_rad: float  # error of the bat face angle at impact
    max_force_n: float  # arm force limit on the bat
    max_torque_nm: float
    max_speed: float  # m/s, fastest bat speed
    pace: float  # m/s, preferred horizontal speed of its strokes


# Elite strokes reach 20-30 m/s ball speed with ~15 m/s bat speed, and elite reaction times to a
# struck ball are ~0.1-0.2 s. `pro`'s aim and face noise are set so that `pro` against `pro`
# returns every serve and loses its points to the errors of those two noises, in rallies of a
# few shots, not to rallies that never end; the lower levels add error so that matches between
# levels have clear winners.
SKILLS = {
    "pro": Skill(reaction_s=0.10, aim_noise_m=0.25, face_noise_rad=0.05, max_force_n=120.0,
                 max_torque_nm=4.0, max_speed=18.0, pace=9.0),
    "club": Skill(reaction_s=0.16, aim_noise_m=0.35, face_noise_rad=0.07, max_force_n=80.0,
                  max_torque_nm=3.0, max_speed=14.0, pace=7.0),
    "novice": Skill(reaction_s=0.25, aim_noise_m=0.50, face_noise_rad=0.10, max_force_n=50.0,
                    max_torque_nm=2.0, max_speed=10.0, pace=5.0),
}
