"""Control laws the built-in behaviours use: our IDM, a speed tracker, a pure-pursuit lane follower.

Plain scalar math (``math``, not numpy: these run once per agent per step, where numpy's
per-call overhead would dominate). Nothing here reads highway-env's class constants; every
gain is a module constant or an argument, so no other code in the process can change how a
scenario's traffic drives.
"""

from __future__ import annotations

import math

__all__ = [
    "IDM", "idm_acceleration", "track_speed", "pure_pursuit_steering", "curve_speed",
    "MAX_STEERING", "MAX_ACCELERATION", "MAX_DECELERATION",
]

MAX_STEERING = math.pi / 3  # [rad] front-wheel angle limit, as highway-env's controller
MAX_ACCELERATION = 6.0  # [m/s^2]
MAX_DECELERATION = 9.0  # [m/s^2] about 0.9 g, emergency braking on dry asphalt


class IDM:
    """Parameters of the Intelligent Driver Model (Treiber et al. 2000).

    Gaps are bumper to bumper (unlike highway-env's centre-to-centre gaps).
    """

    a_max = 2.0  # [m/s^2] comfortable acceleration
    b_comf = 3.0  # [m/s^2] comfortable deceleration
    s0 = 2.0  # [m] jam distance
    time_gap = 1.5  # [s]
    delta = 4.0  # [] velocity exponent


def idm_acceleration(speed: float, target_speed: float, gap: float | None = None,
                     leader_speed: float = 0.0, p: type[IDM] = IDM) -> float:
    """IDM acceleration [m/s^2] at ``speed`` [m/s] toward ``target_speed`` [m/s].

    ``gap`` [m] is the bumper-to-bumper distance to the leader (None: free road) moving at
    ``leader_speed`` [m/s]. The result is clipped to [-MAX_DECELERATION, a_max].
    """
    v = max(speed, 0.0)
    v0 = max(target_speed, 0.1)
    acc = p.a_max * (1.0 - (v / v0) ** p.delta)
    if gap is not None:
        dv = v - leader_speed
        s_star = p.s0 + max(0.0, v * p.time_gap + v * dv / (2.0 * math.sqrt(p.a_max * p.b_comf)))
        acc -= p.a_max * (s_star / max(gap, 0.1)) ** 2
    return min(max(acc, -MAX_DECELERATION), p.a_max)


def track_speed(speed: float, target_speed: float, tau: float = 0.6,
                a_max: float = 3.0, b_max: float = 6.0) -> float:
    """Proportional speed control [m/s^2]: close the speed error in ``tau`` [s], clipped."""
    return min(max((target_speed - speed) / tau, -b_max), a_max)


def pure_pursuit_steering(x: float, y: float, heading: float, tx: float, ty: float,
                          length: float) -> float:
    """Front-wheel angle [rad] that steers highway-env's bicycle at (x, y, heading) onto (tx, ty).

    Pure pursuit: the circle through the target point has curvature ``2 sin(alpha) / ld``.
    highway-env's bicycle moves the centre at slip angle ``beta = atan(tan(delta) / 2)`` and
    turns at ``v sin(beta) / (length / 2)``, i.e. curvature ``2 sin(beta) / length``; equate
    and invert. ``length`` [m] is the vehicle length.
    """
    dx, dy = tx - x, ty - y
    ld = math.hypot(dx, dy)
    if ld < 1e-6:
        return 0.0
    alpha = math.atan2(dy, dx) - heading
    alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
    sin_beta = min(max(length * math.sin(alpha) / ld, -1.0), 1.0)
    beta = math.asin(sin_beta)
    if abs(beta) >= math.pi / 2 - 1e-6:
        return math.copysign(MAX_STEERING, beta)
    delta = math.atan(2.0 * math.tan(beta))
    return min(max(delta, -MAX_STEERING), MAX_STEERING)


def curve_speed(radius: float, lateral_acc: float = 2.5) -> float:
    """Highest speed [m/s] through a curve of ``radius`` [m] at ``lateral_acc`` [m/s^2]."""
    return math.sqrt(max(lateral_acc * radius, 0.0))
