"""Control laws the built-in behaviours use: our IDM, a speed tracker, a lane-keeping steer.

Plain scalar math (``math``, not numpy: these run once per agent per step, where numpy's
per-call overhead would dominate). Nothing here reads highway-env's class constants; every
gain is a module constant or an argument, so no other code in the process can change how a
scenario's traffic drives.
"""

from __future__ import annotations

import math

from .geometry import wrap_to_pi

__all__ = [
    "IDM", "idm_acceleration", "track_speed", "lane_steering", "curve_speed",
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


def lane_steering(speed: float, heading: float, lateral_error: float, path_heading: float,
                  length: float, k_lateral: float = 1 / 0.6, k_heading: float = 1 / 0.2) -> float:
    """Front-wheel angle [rad] that brings a vehicle onto a path and keeps it there.

    A cascade: the lateral error [m] (positive: the vehicle is left of where it should be) asks
    for a lateral speed ``-k_lateral * error`` [m/s], i.e. a heading offset from the path
    heading ``path_heading`` [rad] (taken a little ahead, which anticipates curves); the
    heading error asks for a yaw rate ``k_heading * error`` [rad/s], which highway-env's
    bicycle (slip ``beta = atan(tan(delta)/2)``, yaw rate ``v sin(beta) / (length/2)``)
    turns into a steering angle. ``length`` [m] is the vehicle length.
    """
    v = speed if abs(speed) > 0.1 else math.copysign(0.1, speed if speed else 1.0)
    lateral_speed = -k_lateral * lateral_error
    offset = math.asin(min(max(lateral_speed / v, -1.0), 1.0))
    offset = min(max(offset, -math.pi / 4), math.pi / 4)
    err = path_heading + offset - heading
    err = wrap_to_pi(err)
    yaw_rate = k_heading * err
    sin_beta = min(max(length / 2 * yaw_rate / v, -1.0), 1.0)
    delta = math.atan(2.0 * math.tan(math.asin(sin_beta)))
    return min(max(delta, -MAX_STEERING), MAX_STEERING)


def curve_speed(radius: float, lateral_acc: float = 2.5) -> float:
    """Highest speed [m/s] through a curve of ``radius`` [m] at ``lateral_acc`` [m/s^2]."""
    return math.sqrt(max(lateral_acc * radius, 0.0))
