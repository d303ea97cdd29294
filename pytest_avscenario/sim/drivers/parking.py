"""Parallel parking, the autopilot's manoeuvre for a parking goal: plan, then track.

:class:`Parker` drives the manoeuvre once the autopilot has reached the slot: it measures the
slot from the parked cars it sees, plans two reverse arcs (:func:`parking_path`) or, in a
tight slot, several moves (:func:`parking_moves`), checks the planned footprints against the
parked cars, and tracks the plan with curvature feed-forward and feedback. The planners are
pure geometry in the slot frame (origin at the goal, +x along the goal heading, the car on
the +y side), integrating highway-env's own bicycle kinematics so the plan is what the car
can drive.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..geometry import box_corners, boxes_overlap, poses_hit_boxes, wrap_to_pi
from .route_path import RoutePath, bicycle_steering

__all__ = ["Parker", "parking_path", "parking_moves"]


class Parker:
    """Parallel parking into a slot: approach, reverse on two arcs, pull forward, hold.

    Works in the slot frame (origin at the goal, +x along the goal heading), mirrored so the
    ego always comes from the +y side; steering is mirrored back on output.
    """

    def __init__(self, goal: dict, o: Any, ego: Any, seen: Any) -> None:
        # ``o``: the AutopilotOptions; ``ego``: the observation's ego state; ``seen``: what
        # the autopilot perceives (agents with x, y, vx, vy, c, s, hl, hw)
        self.o = o
        self.gx, self.gy = float(goal["x"]), float(goal["y"])
        self.gh = float(goal.get("heading", 0.0))
        self.c, self.s = math.cos(self.gh), math.sin(self.gh)
        self.slot_length = goal.get("length")
        self.length = L = ego.length
        kappa_max = 2.0 * math.sin(math.atan(0.5 * math.tan(o.max_steering))) / L
        # Keep 5% of the steering range for feedback (the reference is exact for this model).
        self.radius = 1.0 / (0.95 * kappa_max)
        self.min_radius = 1.0 / kappa_max
        self.end_x = 0.0
        self._parked: list = []
        self._boxes: list = []
        self._queue: list = []
        self._traffic = False
        self.phase = "approach"
        self._track: np.ndarray | None = None
        self._arc: np.ndarray | None = None
        self._k = 0
        self._dir = -1.0
        self.plan(ego, seen)

    def plan(self, ego: Any, seen: Any) -> None:
        """(Re)compute the start point from the ego's lateral offset and the parked cars."""
        o, L = self.o, self.length
        _, ye, _ = self._frame(ego.x, ego.y, ego.heading, 1.0)
        self.side = 1.0 if ye >= 0.0 else -1.0
        self.lateral = max(abs(ye), 0.5)
        if self.slot_length is not None:
            self.end_x = min(0.0, -0.5 * float(self.slot_length) + o.parking_clearance + 0.5 * L)
        # Moving agents near the ego (passing traffic) delay the start of the manoeuvre.
        self._traffic = any(
            math.hypot(a.vx, a.vy) > 0.5 and math.hypot(a.x - ego.x, a.y - ego.y) < 30.0
            and (a.x - ego.x) * a.vx + (a.y - ego.y) * a.vy < 0.0  # coming closer
            for a in seen.agents)
        if seen.n:
            # The cars parked around the slot, in the slot frame, inflated by 0.2 m: what the
            # manoeuvre must not touch.
            self._parked = []
            self._boxes = []
            best = None
            for a in seen.agents:
                x, y, h = self._frame(a.x, a.y, math.atan2(a.s, a.c), self.side)
                if abs(y) < 1.5 and -15.0 < x < 15.0:
                    self._parked.append(box_corners(x, y, h, a.hl + 0.2, a.hw + 0.2))
                    ch, sh = abs(math.cos(h)), abs(math.sin(h))
                    # 0.3 m for the multi-move plan: its moves end right at the margin,
                    # and stopping overshoots by a few centimetres.
                    self._boxes.append((x, y, a.hl * ch + a.hw * sh + 0.3,
                                        a.hl * sh + a.hw * ch + 0.3))
                    if x < 0.0:
                        front = x + a.hl * abs(math.cos(h)) + a.hw * abs(math.sin(h))
                        best = front if best is None else max(best, front)
            if best is not None and self.slot_length is None:
                # Reverse in as far as the car behind the slot allows (more room for the
                # nose to swing in past the car in front), then pull forward to the goal.
                self.end_x = min(0.0, max(-3.0, best + o.parking_clearance + 0.5 * L))
        # Length the two reverse arcs need (see parking_path): 2 R cos(b) sin(phi).
        reff = self.radius * math.cos(math.asin(min(0.99, 0.5 * L / self.radius)))
        phi = math.acos(max(-1.0, 1.0 - self.lateral / (2.0 * reff)))
        self.start_x = self.end_x + 2.0 * reff * math.sin(phi)

    def _frame(self, x: float, y: float, h: float, side: float) -> tuple[float, float, float]:
        dx, dy = x - self.gx, y - self.gy
        return (dx * self.c + dy * self.s, side * (-dx * self.s + dy * self.c),
                side * wrap_to_pi(h - self.gh))

    def approach_offset(self, path: RoutePath, s_ego: float, width: float) -> float:
        """Offset [m] (left +) from the route centre line to drive the approach at.

        Passing the car in front of the slot as closely as safe (0.4 m) shortens the two
        reverse arcs, hence the kerb length the manoeuvre needs.
        """
        if self.phase != "approach":
            return 0.0
        x, y = path.point(s_ego)
        sx, sy, _ = self._frame(x, y, 0.0, self.side)
        if not -5.0 < sx - self.start_x < 40.0:
            return 0.0
        shift = max(0.0, sy - (width + self.o.parking_side_clearance))
        tx, ty = path.tangent(s_ego)
        # Toward the slot is the (mirrored) slot frame's -y: side * (sin gh, -cos gh); its
        # component on the path's left normal (-ty, tx) says which way to shift.
        toward_left = -self.side * (self.s * ty + self.c * tx)
        return shift if toward_left > 0 else -shift

    def approach_distance(self, ego: Any) -> float | None:
        """Centre distance [m] still to drive before the reverse manoeuvre may start."""
        if self.phase != "approach":
            return None
        x, _, _ = self._frame(ego.x, ego.y, ego.heading, self.side)
        d = self.start_x + 0.3 - x
        # Only steer the approach stop once near the slot; before that, drive normally.
        return d if d < 40.0 else None

    def maybe_start(self, ego: Any) -> None:
        """Begin reversing once stopped at the start point, if the manoeuvre fits.

        The planned footprints are checked against the parked cars it has seen (inflated
        by 0.2 m); a slot too short for its one-manoeuvre technique is given up, and it drives
        on (phase "abandoned") rather than touch a car.
        """
        x, y, h = self._frame(ego.x, ego.y, ego.heading, self.side)
        if self.phase == "approach" and abs(ego.speed) < 0.05 and x > self.start_x - 0.1 \
                and x < self.start_x + 30.0:
            if self._traffic:
                return  # the nose swings toward the next lane: let passing traffic go first
            pts = parking_path(max(x, self.start_x), y, self.end_x, self.radius, self.length,
                               min_radius=self.min_radius)
            hl, hw = 0.5 * self.length, 0.5 * ego.width
            fits = not any(boxes_overlap(box_corners(px, py, ph, hl, hw), car)
                           for px, py, ph in pts[::2] for car in self._parked)
            if fits:
                queue = [(pts, -1.0)]
                if self.end_x < -0.3:  # reversed in short of the goal: pull forward to it
                    n = max(2, int(math.ceil(-self.end_x / 0.2)))
                    queue.append((np.array([(self.end_x * (1 - i / n), 0.0, 0.0)
                                            for i in range(n + 1)]), 1.0))
            else:
                # Too tight for one manoeuvre: search a multi-move plan (see parking_moves).
                max_beta = math.asin(min(0.99, 0.5 * self.length / self.radius))
                queue = parking_moves(max(x, self.start_x), y, self.length, ego.width, max_beta,
                                      self._boxes)
                if not queue:
                    self.phase = "abandoned"
                    return
            self._queue = queue[1:]
            self._begin(*queue[0])

    def _begin(self, pts: np.ndarray, direction: float) -> None:
        self.phase = "reverse" if direction < 0 else "forward"
        self._track = pts
        seg = np.hypot(np.diff(pts[:, 0]), np.diff(pts[:, 1]))
        self._arc = np.concatenate([[0.0], np.cumsum(seg)])
        self._k = 0
        self._dir = direction

    def act(self, ego: Any, dt: float) -> tuple[float, float]:
        o = self.o
        v = ego.speed
        if self.phase == "done":
            return (-v / dt if abs(v) > 1e-9 else 0.0), 0.0
        x, y, h = self._frame(ego.x, ego.y, ego.heading, self.side)
        pts, arc = self._track, self._arc
        # Progress: nearest point a little around the last one (the path may loop close).
        k0, k1 = self._k, min(len(pts), self._k + 30)
        d2 = (pts[k0:k1, 0] - x) ** 2 + (pts[k0:k1, 1] - y) ** 2
        self._k = k = k0 + int(np.argmin(d2))
        # Longitudinal: remaining distance along the path, projected past the last point.
        ex, ey = pts[-1, 0], pts[-1, 1]
        eh = pts[-1, 2]
        along_end = (ex - x) * math.cos(eh) + (ey - y) * math.sin(eh)
        rem = max(0.0, arc[-1] - arc[k]) if k < len(pts) - 1 else 0.0
        if k >= len(pts) - 3:
            rem = max(0.0, self._dir * along_end)
        if rem < 0.05 and abs(v) < 0.05:
            if self._queue:
                self._begin(*self._queue.pop(0))
            else:
                self.phase = "done"
            return -v / dt, 0.0
        v_des = self._dir * min(o.parking_speed, math.sqrt(2.0 * 0.8 * max(rem, 0.0)))
        accel = max(-2.0, min(2.0, (v_des - v) / 0.5))
        if rem < 0.05:
            accel = -v / dt
        # Lateral: the planned curvature fed forward, plus feedback on the lateral and heading
        # errors. Curvature is of the path as travelled (dh/ds along the motion); reversing,
        # highway-env's centre turns at -2 sin(beta)/L per metre, hence the sign flip. The
        # gains (k_y < k_h / (L/2)) keep the reverse loop stable: in reverse the slip angle
        # pushes the lateral error the wrong way first.
        kk = min(k, len(pts) - 2)
        seg = max(arc[kk + 1] - arc[kk], 1e-6)
        kappa_ref = wrap_to_pi(pts[kk + 1, 2] - pts[kk, 2]) / seg
        # Reference direction of motion from the points (it differs from the body heading
        # by the slip angle).
        th = math.atan2(pts[kk + 1, 1] - pts[kk, 1], pts[kk + 1, 0] - pts[kk, 0])
        ph = pts[kk, 2]
        e_y = -(x - pts[kk, 0]) * math.sin(th) + (y - pts[kk, 1]) * math.cos(th)
        e_h = wrap_to_pi(h - ph)
        kappa = kappa_ref - 0.3 * e_y - 1.5 * e_h
        steer = bicycle_steering(self._dir * kappa, ego.length, o.max_steering)
        return accel, self.side * steer


def parking_path(
    start_x: float,
    lateral: float,
    end_x: float,
    radius: float,
    length: float,
    step: float = 0.2,
    min_radius: float | None = None,
) -> np.ndarray:
    """Reverse parking reference in the slot frame, as rows (x, y, body heading) [m, m, rad].

    Slot frame: origin on the slot's centre line, +x along the traffic direction, the
    driving lane at +y (``lateral`` [m] > 0 from the slot's centre line). The car starts at
    (``start_x``, ``lateral``) heading 0 and ends near (``end_x``, 0) heading 0, reversing all
    the way: straight while the start is further forward than needed, then steering so the
    body turns at 1/``radius`` per metre (tail toward the kerb), then the mirrored counter-
    steer until the body is straight again.

    The points are produced by integrating highway-env's own kinematics (the *centre* moves
    along heading + beta + pi when reversing), not by drawing circles: with a constant slip
    angle -b the centre's path is an arc of radius R cos(b) whose tangent is offset from the
    body by b, and each steering change kinks it. Two such arcs turning the body by phi shift
    the car 2 R cos(b) (1 - cos phi) sideways over 2 R cos(b) sin phi lengthwise. When the
    start is too close for ``radius`` the turn is tightened to fit, down to ``min_radius``
    [m] (the steering limit; default just above the car's half length).
    """
    if lateral <= 0.0:
        raise ValueError("parking_path expects the car on the +y side of the slot")
    half = 0.5 * length

    def solve(r: float) -> tuple[float, float, float]:
        b = math.asin(min(0.99, half / r))
        reff = r * math.cos(b)
        phi = math.acos(max(-1.0, 1.0 - lateral / (2.0 * reff)))
        return b, phi, 2.0 * reff * math.sin(phi)

    b, phi, need = solve(radius)
    span = start_x - end_x
    if span < need:
        # Tighten: bisect the radius whose manoeuvre fits in the available length.
        lo = half * 1.01 if min_radius is None else min(min_radius, radius)
        hi = radius
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if solve(mid)[2] > span:
                hi = mid
            else:
                lo = mid
        radius = lo
        b, phi, need = solve(radius)
    ds = 0.01
    x, y, h = start_x, lateral, 0.0
    pts = [(x, y, h)]
    travelled = 0.0
    next_mark = step
    straight = max(0.0, span - need)
    # Phases as (slip angle, end test); reversing: the centre moves along h + beta + pi and
    # the body turns at -v sin(beta) / (L/2) per unit time, i.e. -2 sin(beta)/L per metre.
    phases = ((0.0, lambda: travelled >= straight),
              (-b, lambda: h >= phi),
              (b, lambda: h <= 0.0))
    for beta, done in phases:
        while not done():
            x -= ds * math.cos(h + beta)
            y -= ds * math.sin(h + beta)
            h -= ds * math.sin(beta) / half
            travelled += ds
            if travelled >= next_mark:
                pts.append((x, y, h))
                next_mark += step
    pts.append((x, y, 0.0))
    return np.array(pts)


def _arc_poses(x0: float, y0: float, h0: float, direction: float, beta: float, half: float,
               s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses after travelling arc lengths ``s`` [m] at a constant slip angle ``beta`` [rad].

    Closed form of highway-env's kinematics: the heading turns at direction sin(beta)/half
    per metre and the centre moves along heading + beta (backward when direction < 0).
    """
    if abs(beta) < 1e-9:
        c, sn = math.cos(h0), math.sin(h0)
        return x0 + direction * s * c, y0 + direction * s * sn, np.full_like(s, h0)
    k = math.sin(beta) / half
    h = h0 + direction * k * s
    x = x0 + (np.sin(h + beta) - math.sin(h0 + beta)) / k
    y = y0 - (np.cos(h + beta) - math.cos(h0 + beta)) / k
    return x, y, h





def parking_moves(
    x: float, y: float, length: float, width: float, max_beta: float,
    boxes: Sequence[tuple[float, float, float, float]], step: float = 0.2,
) -> list[tuple[np.ndarray, float]] | None:
    """A multi-move parallel-parking plan in the slot frame, or None if none is found.

    Frame as for :func:`parking_path` (goal at the origin heading 0, the car at (``x``,
    ``y``) heading 0 with y > 0); ``boxes`` are the obstacles, already inflated by the
    wanted clearance. The plan: reverse (straight to x1, then full lock swinging the tail in
    until the body is at phi), then counter-lock; while the body is not yet straight,
    alternately pull forward on the kerb-side lock and reverse on the counter-lock, each
    move running until the body is straight or the next step would touch an obstacle; then
    a straight move to x = 0. x1 and phi are searched on a grid, preferring a final lateral
    error under 0.15 m and few moves. Returns [(points (x, y, body heading), direction)],
    points every ``step`` metres, direction -1 reversing, +1 forward.
    """
    half, half_w = 0.5 * length, 0.5 * width
    ds = 0.05
    s_grid = np.arange(ds, 15.0, ds)

    def run(x0, y0, h0, direction, beta, stop_h):
        X, Y, H = _arc_poses(x0, y0, h0, direction, beta, half, s_grid)
        bad = poses_hit_boxes(X, Y, H, half, half_w, boxes)
        n = len(s_grid)
        i = int(np.argmax(bad)) if bad.any() else n
        if stop_h is not None and beta:
            turn = direction * math.sin(beta)
            done = (H - stop_h) * (1.0 if turn > 0 else -1.0) >= 0.0
            if done.any():
                i = min(i, int(np.argmax(done)) + 1)
        if i == 0:
            return x0, y0, h0, 0.0
        return float(X[i - 1]), float(Y[i - 1]), float(H[i - 1]), float(s_grid[i - 1])

    best = None
    for x1 in np.arange(x, -2.0, -0.5):
        # The straight reverse to x1 must itself be clear.
        if poses_hit_boxes(np.array([x1]), np.array([y]), np.array([0.0]), half, half_w, boxes)[0]:
            break
        for phi in np.arange(0.3, 1.0, 0.05):
            moves = [(x, y, 0.0, -1.0, 0.0, x - x1)]
            cx, cy, ch, s = run(x1, y, 0.0, -1.0, -max_beta, phi)
            if ch < phi - 0.01:
                continue
            moves.append((x1, y, 0.0, -1.0, -max_beta, s))
            ok = False
            for _ in range(8):
                for direction, beta in ((-1.0, max_beta), (1.0, -max_beta)):
                    nx, ny, nh, s = run(cx, cy, ch, direction, beta, 0.0)
                    if s < 0.05:
                        break
                    moves.append((cx, cy, ch, direction, beta, s))
                    cx, cy, ch = nx, ny, nh
                    if abs(ch) < 0.02:
                        ok = True
                        break
                else:
                    continue
                break
            if not ok:
                continue
            # Final straight move to x = 0 must be clear too.
            xs = np.linspace(cx, 0.0, 20)
            if poses_hit_boxes(xs, np.full_like(xs, cy), np.full_like(xs, ch), half, half_w, boxes).any():
                continue
            cost = 10.0 * abs(cy) + len(moves)
            if best is None or cost < best[0]:
                best = (cost, moves, (cx, cy, ch))
        if best is not None and best[0] < 10.0 * 0.15 + 4:
            break  # good enough: stop searching further back
    if best is None or abs(best[2][1]) > 0.3:
        return None
    # Sample the moves into tracks; consecutive moves in the same direction merge.
    tracks: list[tuple[list, float]] = []
    for x0, y0, h0, direction, beta, s in best[1]:
        n = max(1, int(math.ceil(s / step)))
        ss = np.linspace(0.0, s, n + 1)
        X, Y, H = _arc_poses(x0, y0, h0, direction, beta, half, ss)
        pts = list(zip(X.tolist(), Y.tolist(), H.tolist()))
        if tracks and tracks[-1][1] == direction:
            tracks[-1][0].extend(pts[1:])
        else:
            tracks.append((pts, direction))
    cx, cy, ch = best[2]
    if abs(cx) > 0.1:
        direction = 1.0 if cx < 0.0 else -1.0
        n = max(2, int(math.ceil(abs(cx) / step)))
        pts = [(cx + (0.0 - cx) * i / n, cy, ch) for i in range(n + 1)]
        if tracks and tracks[-1][1] == direction:
            tracks[-1][0].extend(pts[1:])
        else:
            tracks.append((pts, direction))
    return [(np.array(p), d) for p, d in tracks if len(p) >= 2]
