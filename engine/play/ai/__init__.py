"""Bat AI: predicts the ball with the engine itself, aims, solves the stroke, plays it through the arm."""
from engine.play.ai.aim import shoot, shot_and_stroke, stroke
from engine.play.ai.player import BatAI, Plan, Segment
from engine.play.ai.predict import (HALF_LENGTH, HALF_WIDTH, MEMO_SIZE, NO_STRIKE, PAUSED, STOP_CONTACT, STOP_EVENTS,
                                    STOP_RETURN_STRIKE, STOP_SERVE_STRIKE, free_flight_marks, predict_flight,
                                    predict_span, reset_memo, strike_index)
from engine.play.ai.skill import SKILLS, Skill
# The arm's control law and its array layouts, as the AI's users have always imported them.
from engine.play.arm import (BAT_ANG_VEL, BAT_FLOATS, BAT_POS, BAT_QUAT, BAT_VEL, CTL_D_ANGLE, CTL_HOLD, CTL_INERTIA,
                             CTL_K_ANGLE, CTL_KD, CTL_KP, CTL_MASS, CTL_MAX_FORCE, CTL_MAX_SPEED, CTL_MAX_TORQUE,
                             CTL_N_SEGMENTS, CTL_NORMAL, CTL_SEGMENTS, CTL_SIZE, MAX_SEGMENTS, SEG_P0, SEG_P1, SEG_T0,
                             SEG_T1, SEG_V0, SEG_V1, SEG_WIDTH, bat_control, control_bats)

__all__ = [
    # player
    "BatAI", "Plan", "Segment",
    # skill
    "SKILLS", "Skill",
    # predict
    "HALF_LENGTH", "HALF_WIDTH", "MEMO_SIZE", "NO_STRIKE", "PAUSED", "STOP_CONTACT", "STOP_EVENTS",
    "STOP_RETURN_STRIKE", "STOP_SERVE_STRIKE", "free_flight_marks", "predict_flight", "predict_span", "reset_memo",
    "strike_index",
    # aim
    "shoot", "shot_and_stroke", "stroke",
    # engine.play.arm
    "BAT_ANG_VEL", "BAT_FLOATS", "BAT_POS", "BAT_QUAT", "BAT_VEL", "CTL_D_ANGLE", "CTL_HOLD", "CTL_INERTIA",
    "CTL_K_ANGLE", "CTL_KD", "CTL_KP", "CTL_MASS", "CTL_MAX_FORCE", "CTL_MAX_SPEED", "CTL_MAX_TORQUE",
    "CTL_N_SEGMENTS", "CTL_NORMAL", "CTL_SEGMENTS", "CTL_SIZE", "MAX_SEGMENTS", "SEG_P0", "SEG_P1", "SEG_T0",
    "SEG_T1", "SEG_V0", "SEG_V1", "SEG_WIDTH", "bat_control", "control_bats",
]
