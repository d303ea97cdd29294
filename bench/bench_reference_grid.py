"""The careful reference driver behind a braking lead, against its own closed form.

The grid of issue #26 (item 1): ego and lead at the same speed ``v`` on the middle lane of a
three-lane road with a 30 m/s limit, ``time_gap * v`` of bumper gap between them; the lead
brakes at ``decel`` to a stop 3 s into the run. 48 cases: v 15/20/25/30 m/s, time gap
1/1.5/2/3 s, decel 2/4/6 m/s^2. For each driver the cases that collide, and for the careful
driver the closed form :func:`braking_lead_min_gap` in two readings:

* ``nominal``: from the scenario's numbers (both at ``v``, gap ``time_gap * v``, the ego
  holding its speed until it reacts) — the regulation's driver dropped into the case;
* ``at onset``: from the state when the lead's braking becomes perceivable — when it starts,
  or when the lead comes within the ego's sensor range (80 m, centre to centre) if later —
  with the ego's speed, gap and acceleration then (ordinary driving before it, IDM toward
  the 30 m/s limit, changes them a little).

    PYTHONPATH=$PWD python bench/bench_reference_grid.py [--drivers careful,idm,autopilot]
        [--sensor-range 80]
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from pytest_avscenario.sim import World
from pytest_avscenario.sim import behaviors as b

SPEEDS = (15.0, 20.0, 25.0, 30.0)  # [m/s]
TIME_GAPS = (1.0, 1.5, 2.0, 3.0)  # [s]
DECELS = (2.0, 4.0, 6.0)  # [m/s^2]
BRAKE_AT = 3.0  # [s]
EGO_S = 20.0  # [m]
TARGET = None


def run_case(driver, v, time_gap, decel, sensor_range=None, dt=0.1):
    world = World(seed=0)
    if sensor_range is not None:
        world.sensor_range = sensor_range
    road = world.straight_road(lanes=3, length=1200.0, speed_limit=30.0)
    world.ego(road.lane(1), s=EGO_S, speed=v, driver=driver, target_speed=TARGET)
    world.car(road.lane(1), s=EGO_S + 5.0 + time_gap * v, speed=v, name="lead",
              behavior=b.brake_at(BRAKE_AT, decel=decel))
    return world.run(BRAKE_AT + v / decel + 6.0, dt=dt)


def gaps(traj):
    """Bumper gap [m] ego -> lead at every sample (both on one straight lane along x)."""
    return traj.x[1] - traj.x[0] - 0.5 * (traj.length[0] + traj.length[1])


def onset_index(traj, sensor_range):
    """The sample where the lead's braking becomes perceivable: when it starts, or when it
    first comes within the ego's sensor range (centre to centre) if that is later."""
    k_brake = int(round(BRAKE_AT / traj.dt))
    seen = np.hypot(traj.x[1] - traj.x[0], traj.y[1] - traj.y[0]) <= sensor_range
    return max(k_brake, int(np.argmax(seen)))


def main(argv=None):
    from pytest_avscenario.sim.drivers.reference import braking_lead_min_gap

    ap = argparse.ArgumentParser()
    ap.add_argument("--drivers", default="careful,idm,autopilot")
    ap.add_argument("--sensor-range", type=float, default=None)
    args = ap.parse_args(argv)
    cases = list(itertools.product(SPEEDS, TIME_GAPS, DECELS))
    for driver in args.drivers.split(","):
        t0 = time.perf_counter()
        hit, nominal, onset, disagree = [], [], [], []
        for v, tg, d in cases:
            traj = run_case(driver, v, tg, d, args.sensor_range)
            crashed = bool(traj.crashed[0].any())
            if crashed:
                hit.append((v, tg, d))
            if driver != "careful":
                continue
            k = onset_index(traj, args.sensor_range or 80.0)
            nom = braking_lead_min_gap(tg * v, v, v, d)
            at = braking_lead_min_gap(float(gaps(traj)[k]), float(traj.speed[0, k]),
                                      float(traj.speed[1, k]), d,
                                      accel=float(traj.signals["ego.acceleration"][k + 1]))
            nominal.append(nom <= 0)
            onset.append(at <= 0)
            if (at <= 0) != crashed:
                disagree.append((v, tg, d, round(at, 3), round(float(gaps(traj).min()), 3)))
        ms = (time.perf_counter() - t0) * 1e3 / len(cases)
        print(f"{driver:10s} collides in {len(hit):2d}/{len(cases)} ({ms:.0f} ms/case)")
        if driver == "careful":
            print(f"{'':10s} closed form: nominal {sum(nominal)}, at onset {sum(onset)}; "
                  f"simulation disagrees with it at onset in {len(disagree)}: {disagree}")
        if hit:
            print(f"{'':10s} colliding (v, time gap, decel): {hit}")


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
