"""A hand-made stand-and-balance policy: ankle pitch from the gravity tilt (a leaky integral,
so the body is brought upright and a push is answered without wind-up) and the pitch rate.

    darwin policy run clients.learn.examples.stand_balance:policy

Gains found by a small grid search on the fast backend with 0.1 s pushes of 9 and 12 N along
the body's x axis (tests/learn/test_policy_runner.py checks it outlasts holding the stand). The
servo directions are mirrored left/right, hence opposite signs on r/l ankle pitch.
"""

from __future__ import annotations

import numpy as np

from schemas.joints import JOINT_NAMES
from schemas.policy import N_JOINTS, OBSERVATION_LAYOUT

KI = -2.0  # action units per (gravity x × s)
KD = -0.4  # action units per rad/s of pitch rate
LEAK = 0.95  # per step: the integral forgets, a push is not answered for ever
R_ANKLE = JOINT_NAMES.index("r_ankle_pitch")
L_ANKLE = JOINT_NAMES.index("l_ankle_pitch")
_AT = {name: sum(n for _, n in OBSERVATION_LAYOUT[:i]) for i, (name, _) in
       enumerate(OBSERVATION_LAYOUT)}  # fmt: skip


class StandBalance:
    rate_hz = 50.0

    def __init__(self) -> None:
        self.integral = 0.0

    def reset(self) -> None:
        self.integral = 0.0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        gravity_x = float(obs[_AT["gravity"]])
        pitch_rate = float(obs[_AT["gyro"] + 1])
        self.integral = float(np.clip(LEAK * self.integral + KI * gravity_x / self.rate_hz, -1, 1))
        u = self.integral + KD * pitch_rate
        action = np.zeros(N_JOINTS)
        action[R_ANKLE], action[L_ANKLE] = u, -u
        return np.clip(action, -1.0, 1.0)


policy = StandBalance()


def hold(obs: np.ndarray) -> np.ndarray:
    """The baseline: hold the default stand pose."""
    return np.zeros(N_JOINTS)
