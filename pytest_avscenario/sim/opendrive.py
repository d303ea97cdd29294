"""OpenDRIVE maps: every lane of a ``.xodr`` file as plain data, loaded once per process.

:func:`load` reads a map file into a :class:`MapData`: each lane of each lane section, named
``"road/section/lane"`` (``"12/0/-1"``: road 12, its first lane section, the first lane right
of the reference line), with its OpenDRIVE type (``kind``: driving, shoulder, sidewalk…),
its centre line and width sampled every :data:`STEP` metres in its direction of travel, its
speed limit, and its successors and predecessors in the direction of travel, across lane
sections, road links and junction connections.

The road reference lines (line, arc, spiral, poly3, paramPoly3) are evaluated by ``pyxodr``
(the ``maps`` extra) at 0.1 m; lane offsets and widths are evaluated here, from the file's own
polynomials, on that line. pyxodr's hazards are kept out: its arc check writes
``arc_error.pdf`` into the working directory and raises when one sample step turns by more
than 0.2 rad, so every road with a tight arc is evaluated at a resolution fine enough never to
reach that check; any other failure becomes a :class:`MapError` naming the file, the road and
the geometry. Left-hand-traffic roads (``rule="LHT"``) drive on their left lanes.

Maps are cached by the SHA-256 of their bytes, so a map read by a collection-time parameter
(:class:`MapLane`) and by every case's world is parsed once per process. Nothing here imports
highway-env; :mod:`.maps` makes highway-env lanes of this data.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..space import Choice, SpaceError
from .errors import SimError

__all__ = ["MapError", "MapData", "LaneData", "load", "resolve_path", "MapLane", "DRIVABLE",
           "STEP"]

#: lane types a vehicle may drive on; the world's roads (and so ``on_road``) are these
DRIVABLE = frozenset({"driving", "entry", "exit", "onRamp", "offRamp", "connectingRamp",
                      "bidirectional", "parking"})
#: [m] spacing of the samples kept of every lane's centre line and width
STEP = 0.5
#: [m] resolution at which pyxodr evaluates the reference lines
RESOLUTION = 0.1
#: [m] a sample this close to a lane section's end counts as on it (see :func:`_poly`)
_AT_BOUNDARY = 1e-6
#: [rad] largest turn of one sample step pyxodr's arc check accepts is 0.2; we stay below this
_ARC_STEP = 0.15
_GEOMETRIES = ("line", "arc", "spiral", "poly3", "paramPoly3")
_UNITS = {"m/s": 1.0, "km/h": 1 / 3.6, "mph": 0.44704}


class MapError(SimError):
    """A map file that cannot be used: the message names the file and the element."""


@dataclass(frozen=True, eq=False)
class LaneData:
    """One lane of one lane section, sampled in its direction of travel.

    ``s`` [m] is the arc length along the centre line from the lane's start (in travel
    direction), ``xy`` [m] the centre line, ``heading`` [rad] its direction, ``width`` [m]
    the lane's width there (from the file's polynomials, exact at every sample), measured
    square to the reference line (``ref_heading``), as OpenDRIVE measures it.
    ``forward`` says whether traffic runs along the road's reference line.
    """

    id: str
    road: str
    section: int
    lane: int
    kind: str
    forward: bool
    junction: str  # the junction's id, "" on an ordinary road
    s: np.ndarray = field(repr=False)
    xy: np.ndarray = field(repr=False)
    heading: np.ndarray = field(repr=False)
    width: np.ndarray = field(repr=False)
    #: [rad] direction of the road's reference line at each sample, turned to the direction
    #: of travel: widths and offsets are measured square to it (OpenDRIVE's t axis)
    ref_heading: np.ndarray = field(repr=False, default=None)
    speed_limit: float = math.nan  # [m/s], NaN where the file gives none
    successors: tuple[str, ...] = ()
    predecessors: tuple[str, ...] = ()

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """The left and right edges [m] of the lane, as (N, 2) polylines in travel order."""
        n = np.stack([-np.sin(self.ref_heading), np.cos(self.ref_heading)], axis=1)
        half = (self.width / 2)[:, None]
        return self.xy + half * n, self.xy - half * n


@dataclass(frozen=True, eq=False)
class MapData:
    """Every lane of a map file (``lanes`` by id, in file order) and where it came from."""

    path: str
    digest: str
    lanes: dict[str, LaneData]
    junctions: dict[str, tuple[str, ...]]  # junction id -> its lanes
    geometry_starts: tuple[tuple[str, float, float, float], ...]  # (road, s, x, y) of each
    reference: dict[str, Any] = field(repr=False)  # road -> (ss -> (x, y, heading))
    _tree: list = field(default_factory=list, repr=False)

    def of_kind(self, kind: str | Iterable[str] | None = None, min_length: float = 0.0) -> list[LaneData]:
        """Lanes of ``kind`` (a type, several, or None: all) at least ``min_length`` [m] long."""
        kinds = None if kind is None else ({kind} if isinstance(kind, str) else set(kind))
        return [l for l in self.lanes.values()
                if (kinds is None or l.kind in kinds) and l.length >= min_length]

    def closest(self, x: float, y: float, kinds: Iterable[str] | None = None) -> LaneData:
        """The lane (of ``kinds``, default drivable) whose centre line is nearest (x, y) [m]."""
        from shapely import Point

        kinds = DRIVABLE if kinds is None else frozenset(kinds)
        tree, ids = self._index(kinds)
        k = int(tree.query_nearest(Point(float(x), float(y)))[0])
        return self.lanes[ids[k]]

    def _index(self, kinds: frozenset) -> tuple[Any, list[str]]:
        for key, tree, ids in self._tree:
            if key == kinds:
                return tree, ids
        from shapely import LineString, STRtree

        ids = [l.id for l in self.lanes.values() if l.kind in kinds]
        if not ids:
            raise MapError(f"{self.path}: no lane of the kinds {sorted(kinds)}")
        tree = STRtree([LineString(self.lanes[i].xy) for i in ids])
        self._tree.append((kinds, tree, ids))
        return tree, ids


# -- loading ---------------------------------------------------------------------------------------

_CACHE: dict[tuple[str, str], MapData] = {}
_SEEN: dict[tuple, MapData] = {}  # (path, mtime, size, evaluator) -> its map
_LOCK = threading.Lock()


def resolve_path(path: Any, *, base: str | os.PathLike | None = None) -> Path:
    """``path`` as a file: absolute as given, else relative to ``base`` (the calling test
    module's folder when None), then to the working directory."""
    p = Path(os.fspath(path))
    if p.is_absolute():
        return p
    bases = [Path(base)] if base is not None else _caller_dirs()
    for b in bases + [Path.cwd()]:
        if (b / p).is_file():
            return (b / p).resolve()
    return p.resolve()


def _caller_dirs() -> list[Path]:
    """The folder of the first caller outside this package (the test module using a map)."""
    import sys

    frame = sys._getframe(1)
    while frame is not None:
        f = frame.f_code.co_filename
        if f.endswith(".py") and not f.startswith(_PKG) and "importlib" not in f:
            return [_folder_of(f)]
        frame = frame.f_back
    return []


_PKG = str(Path(__file__).resolve().parents[1])


@functools.lru_cache(maxsize=256)
def _folder_of(source: str) -> Path:
    # a module's folder, resolved once (every world that loads a map asks, once per case)
    return Path(source).resolve().parent


def load(path: Any, *, base: Any = None, evaluator: str = "numpy") -> MapData:
    """The map in ``path`` (see :func:`resolve_path`), parsed once per process per content.

    ``evaluator`` evaluates the reference lines: ``"numpy"`` (this module, exact for lines
    and arcs) or ``"pyxodr"`` (the ``maps`` extra; bench/bench_maps.py compares them).
    """
    if evaluator not in ("numpy", "pyxodr"):
        raise MapError(f"evaluator={evaluator!r}: use 'numpy' or 'pyxodr'")
    p = resolve_path(path, base=base)
    try:
        st = p.stat()
    except OSError:
        st = None
    seen = (str(p), st.st_mtime_ns, st.st_size, evaluator) if st is not None else None
    if seen is not None and seen in _SEEN:  # the same file unchanged: no need to hash it
        return _SEEN[seen]
    try:
        blob = p.read_bytes()
    except FileNotFoundError:
        raise MapError(f"map file {os.fspath(path)!r} not found (looked for {p})") from None
    except OSError as exc:
        raise MapError(f"map file {p}: cannot be read ({exc})") from None
    digest = hashlib.sha256(blob).hexdigest()
    with _LOCK:
        got = _CACHE.get((digest, evaluator))
        if got is None:
            got = _CACHE[(digest, evaluator)] = _parse(str(p), digest, blob, evaluator)
        if seen is not None:
            _SEEN[seen] = got
    return got


def xml_root(path: str, blob: bytes) -> Any:
    """The root element of a map file's bytes, or a MapError naming the file."""
    try:  # lxml parses a 3-MB map four times faster; the standard library's does the same
        from lxml import etree as ET

        errors: tuple = (ET.XMLSyntaxError,)
        parse = lambda b: ET.fromstring(b, parser=ET.XMLParser(huge_tree=True))  # noqa: E731
    except ImportError:  # pragma: no cover - lxml comes with the maps extra
        import xml.etree.ElementTree as ET

        errors, parse = (ET.ParseError,), ET.fromstring
    try:
        return parse(blob)
    except errors as exc:
        raise MapError(f"map file {path} is not XML ({exc})") from None


def _parse(path: str, digest: str, blob: bytes, evaluator: str) -> MapData:
    root = xml_root(path, blob)
    if root.tag != "OpenDRIVE":
        raise MapError(f"map file {path}: the root element is <{root.tag}>, not <OpenDRIVE>")
    roads = root.findall("road")
    if not roads:
        raise MapError(f"map file {path}: no <road> in it")
    lanes: dict[str, LaneData] = {}
    raw: dict[str, Any] = {}  # road id -> (xml, section records)
    starts = []
    reference: dict[str, Any] = {}
    for road in roads:
        rid = road.get("id", "")
        ref = reference[rid] = _reference(path, road, evaluator)
        for g in road.findall("planView/geometry"):
            starts.append((rid, float(g.get("s")), float(g.get("x")), float(g.get("y"))))
        raw[rid] = (road, _road_lanes(path, road, ref, lanes))
    links = _links(path, root, raw, lanes)
    junctions: dict[str, list[str]] = {}
    for lid, lane in list(lanes.items()):
        succ = tuple(sorted(links.get((lid, "out"), ()), key=_order))
        pred = tuple(sorted(links.get((lid, "in"), ()), key=_order))
        # set once, before anyone sees the lane (the links need every lane first)
        object.__setattr__(lane, "successors", succ)
        object.__setattr__(lane, "predecessors", pred)
        if lane.junction:
            junctions.setdefault(lane.junction, []).append(lid)
    if not any(l.kind in DRIVABLE and l.kind != "parking" for l in lanes.values()):
        raise MapError(f"map file {path}: no driving lane in it (lane types: "
                       f"{sorted({l.kind for l in lanes.values()}) or 'none'})")
    return MapData(path, digest, lanes, {k: tuple(v) for k, v in junctions.items()},
                   tuple(starts), reference)


def _order(lane_id: str) -> tuple:
    road, sec, lane = lane_id.split("/")
    return (int(road) if road.lstrip("-").isdigit() else 0, road, int(sec), int(lane))


def _num(el: Any, attr: str, path: str, where: str, default: float | None = None) -> float:
    v = el.get(attr)
    if v is None:
        if default is not None:
            return default
        raise MapError(f"map file {path}: {where} has no {attr!r}")
    try:
        x = float(v)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise MapError(f"map file {path}: {where} has {attr}={v!r}, not a finite number")
    return x


def _check_geometries(path: str, road: Any) -> list:
    """The road's planView records ``(s, x, y, hdg, length, kind, element)``, checked."""
    rid = road.get("id", "?")
    geoms = road.findall("planView/geometry")
    if not geoms:
        raise MapError(f"map file {path}: road {rid} has no <planView> geometry")
    out = []
    for g in geoms:
        where = f"road {rid} geometry at s={g.get('s')}"
        kinds = [c.tag for c in g if isinstance(c.tag, str)]
        kind = next((k for k in kinds if k in _GEOMETRIES), None)
        if kind is None:
            raise MapError(f"map file {path}: {where} is <{'/'.join(kinds) or 'empty'}>, not one "
                           f"of the geometries {', '.join(_GEOMETRIES)}")
        s, x, y, hdg, glen = (_num(g, a, path, where) for a in ("s", "x", "y", "hdg", "length"))
        if glen <= 0:
            raise MapError(f"map file {path}: {where} has length {glen}, need > 0")
        out.append((s, x, y, hdg, glen, kind, g.find(kind), where))
    out.sort(key=lambda r: r[0])
    return out


def _reference(path: str, road: Any, evaluator: str) -> Any:
    """A function ``ss -> (x, y, heading)`` [m, m, rad] of the road's reference line."""
    geoms = _check_geometries(path, road)
    if evaluator == "pyxodr":
        s_ref, pts, h_ref = _reference_line_pyxodr(path, road, geoms)
        return lambda ss: (np.interp(ss, s_ref, pts[:, 0]), np.interp(ss, s_ref, pts[:, 1]),
                           np.interp(ss, s_ref, h_ref))
    evals = [_geometry(path, rec) for rec in geoms]
    starts = np.array([r[0] for r in geoms])

    def ref(ss: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = np.clip(np.searchsorted(starts, ss, side="right") - 1, 0, len(geoms) - 1)
        x, y, h = np.empty_like(ss), np.empty_like(ss), np.empty_like(ss)
        for j in np.unique(k):
            m = k == j
            x[m], y[m], h[m] = evals[j](ss[m] - starts[j])
        return x, y, h

    return ref


def _geometry(path: str, rec: tuple) -> Any:
    """The function ``u -> (x, y, heading)`` of one planView geometry (u [m] from its start)."""
    s0, x0, y0, hdg, glen, kind, el, where = rec
    c, sn = math.cos(hdg), math.sin(hdg)

    def placed(lu: np.ndarray, lv: np.ndarray, lh: np.ndarray) -> tuple:
        return x0 + c * lu - sn * lv, y0 + sn * lu + c * lv, hdg + lh

    if kind == "line":
        return lambda u: placed(u, np.zeros_like(u), np.zeros_like(u))
    if kind == "arc":
        k = _num(el, "curvature", path, where + " <arc>")
        if k == 0.0:
            return lambda u: placed(u, np.zeros_like(u), np.zeros_like(u))
        return lambda u: placed(np.sin(k * u) / k, (1 - np.cos(k * u)) / k, k * u)
    n = max(int(math.ceil(glen / 0.05)), 8)
    if kind == "spiral":
        k0 = _num(el, "curvStart", path, where + " <spiral>")
        k1 = _num(el, "curvEnd", path, where + " <spiral>")
        dk = (k1 - k0) / glen

        def theta(u: np.ndarray) -> np.ndarray:
            return k0 * u + 0.5 * dk * u * u

        grid = np.linspace(0.0, glen, n + 1)
        mid = theta((grid[:-1] + grid[1:]) / 2)  # the midpoint rule: O(h^2) per step
        h = glen / n
        gu = np.concatenate([[0.0], np.cumsum(h * np.cos(mid))])
        gv = np.concatenate([[0.0], np.cumsum(h * np.sin(mid))])
        return lambda u: placed(np.interp(u, grid, gu), np.interp(u, grid, gv), theta(u))
    if kind == "poly3":
        a, b, cc, d = (_num(el, q, path, where + " <poly3>", 0.0) for q in "abcd")
        pu = np.linspace(0.0, glen, n + 1)  # s >= u: the parameter never runs past the length
        pv = a + pu * (b + pu * (cc + pu * d))
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(pu), np.diff(pv)))])

        def at(u: np.ndarray) -> tuple:
            q = np.interp(u, arc, pu)
            v = a + q * (b + q * (cc + q * d))
            return placed(q, v, np.arctan(b + q * (2 * cc + 3 * d * q)))

        return at
    # paramPoly3
    co = [_num(el, q, path, where + " <paramPoly3>", 0.0)
          for q in ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")]
    top = 1.0 if el.get("pRange", "normalized") == "normalized" else glen

    def at(u: np.ndarray) -> tuple:
        p = u * (top / glen)
        lu = co[0] + p * (co[1] + p * (co[2] + p * co[3]))
        lv = co[4] + p * (co[5] + p * (co[6] + p * co[7]))
        du = co[1] + p * (2 * co[2] + 3 * p * co[3])
        dv = co[5] + p * (2 * co[6] + 3 * p * co[7])
        return placed(lu, lv, np.arctan2(dv, du))

    return at


def _reference_line_pyxodr(path: str, road: Any, geoms: list) -> tuple:
    """The reference line as pyxodr evaluates it: s [m], points (N, 2) [m], heading [rad]."""
    rid = road.get("id", "?")
    length = _num(road, "length", path, f"road {rid}")
    res = RESOLUTION
    for s0, x0, y0, hdg, glen, kind, el, where in geoms:
        if kind == "arc":
            k = abs(float(el.get("curvature")))
            # pyxodr samples an arc in max(int(L / res), 2) points and refuses a first step
            # that turns by more than 0.2 rad (writing arc_error.pdf first): stay under it
            while k * glen / max(int(glen / res) - 1, 1) > _ARC_STEP and res > 1e-4:
                res /= 2
    try:
        from pyxodr.road_objects.road import Road
    except ImportError:
        raise MapError("evaluating maps with pyxodr needs it installed: "
                       "pip install 'pytest-avscenario[maps]'") from None
    try:
        pts = np.asarray(Road(road, resolution=res).reference_line, dtype=float)[:, :2]
    except Exception as exc:  # pyxodr's own errors: name what it could not evaluate
        raise MapError(f"map file {path}: pyxodr cannot evaluate road {rid}'s reference line "
                       f"({', '.join(f'<{g[5]}> at s={g[0]:g}' for g in geoms)}): "
                       f"{type(exc).__name__}: {exc}") from None
    if len(pts) < 2 or not np.isfinite(pts).all():
        raise MapError(f"map file {path}: road {rid}'s reference line is not finite")
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.hypot(*np.diff(pts, axis=0).T) > 1e-9
    pts = pts[keep]
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] > 0:
        s *= length / s[-1]  # sampled chords are a hair shorter than the curve
    d = np.gradient(pts, s, axis=0)
    h = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return s, pts, h


def _headings(pts: np.ndarray) -> np.ndarray:
    """Heading [rad] at each vertex of a polyline: the mean direction of its two segments."""
    d = np.diff(pts, axis=0)
    n = np.hypot(d[:, 0], d[:, 1])
    n[n == 0] = 1.0
    u = d / n[:, None]
    v = np.empty_like(pts)
    v[0], v[-1] = u[0], u[-1]
    v[1:-1] = u[:-1] + u[1:]
    return _unwrap(np.arctan2(v[:, 1], v[:, 0]))


def _unwrap(h: np.ndarray) -> np.ndarray:
    dh = np.diff(h)
    dh -= 2 * np.pi * np.round(dh / (2 * np.pi))
    out = np.empty_like(h)
    out[0] = h[0]
    np.cumsum(dh, out=out[1:])
    out[1:] += h[0]
    return out


def _kind(g: Any) -> str:
    return next((c.tag for c in g if isinstance(c.tag, str) and c.tag in _GEOMETRIES), "?")


def _poly(records: list[tuple[float, float, float, float, float]], s: np.ndarray,
          end: float | None = None) -> np.ndarray:
    """Piecewise cubic ``a + b ds + c ds^2 + d ds^3`` (records sorted by start) at ``s``.

    A record holds on ``[its start, the next record's start)``, so a sample on a boundary takes
    the record that starts there; except at ``end`` (a lane section's end, which is the next
    section's start): samples there take the limit from the left, the record in force just
    before it, so that a record starting exactly where the section ends (its jump belongs to
    the next section) does not move the section's last point."""
    if not records:
        return np.zeros_like(s)
    if len(records) == 1:
        s0, a, b, c, d = records[0]
        ds = s - s0
        return a + ds * (b + ds * (c + ds * d))
    starts = np.array([r[0] for r in records])
    k = np.searchsorted(starts, s, side="right") - 1
    if end is not None:
        at_end = s >= end - _AT_BOUNDARY
        if at_end.any():
            k = np.where(at_end, np.searchsorted(starts, s - _AT_BOUNDARY, side="left") - 1, k)
    k = np.clip(k, 0, len(records) - 1)
    coef = np.array([r[1:] for r in records])
    ds = s - starts[k]
    a, b, c, d = coef[k].T
    return a + ds * (b + ds * (c + ds * d))


def _lane_number(el: Any, path: str, where: str) -> int:
    """A <lane>'s id, a whole number (0 is the centre lane)."""
    raw = el.get("id")
    try:
        return int(raw)
    except (TypeError, ValueError):
        raise MapError(f"map file {path}: {where} has a <lane id={raw!r}>, not a whole "
                       "number") from None


def _records(els: Iterable[Any], start: str, path: str, where: str) -> list:
    out = []
    for e in els:
        out.append((_num(e, start, path, where), _num(e, "a", path, where, 0.0),
                    _num(e, "b", path, where, 0.0), _num(e, "c", path, where, 0.0),
                    _num(e, "d", path, where, 0.0)))
    return sorted(out, key=lambda r: r[0])


def _speed(el: Any, path: str, where: str) -> float:
    if el is None:
        return math.nan
    v = _num(el, "max", path, where, math.nan) if el.get("max") not in (None, "no limit",
                                                                         "undefined") else math.nan
    return v * _UNITS.get(el.get("unit", "m/s"), 1.0)


def _road_lanes(path: str, road: Any, ref: Any, lanes: dict) -> list:
    rid = road.get("id", "?")
    lht = road.get("rule", "RHT").upper() == "LHT"
    junction = road.get("junction", "-1")
    junction = "" if junction in ("-1", "") else junction
    length = _num(road, "length", path, f"road {rid}")
    offsets = _records(road.findall("lanes/laneOffset"), "s", path, f"road {rid} <laneOffset>")
    types = sorted(((_num(t, "s", path, f"road {rid} <type>"), t) for t in road.findall("type")),
                   key=lambda p: p[0])
    sections = road.findall("lanes/laneSection")
    if not sections:
        raise MapError(f"map file {path}: road {rid} has no <laneSection>")
    bounds = [_num(sec, "s", path, f"road {rid} <laneSection>") for sec in sections] + [length]
    out = []
    for k, sec in enumerate(sections):
        s0, s1 = bounds[k], min(bounds[k + 1], length)
        if s1 - s0 < 1e-6:
            out.append((sec, []))
            continue
        n = max(int(math.ceil((s1 - s0) / STEP)), 1) + 1
        ss = np.linspace(s0, s1, n)
        x, y, h = ref(ss)
        nx, ny = -np.sin(h), np.cos(h)
        base = _poly(offsets, ss, end=s1)
        road_speed = next((_speed(t.find("speed"), path, f"road {rid} <type>")
                           for ts, t in reversed(types) if ts <= s0 + 1e-9), math.nan)
        made = []
        for side, sign in (("left", 1.0), ("right", -1.0)):
            ided = [(_lane_number(el, path, f"road {rid} lane section {k} <{side}>"), el)
                    for el in sec.findall(f"{side}/lane")]
            ided.sort(key=lambda t: abs(t[0]))
            inner = np.zeros_like(ss)
            for lid, el in ided:
                where = f"road {rid} lane section {k} lane {lid}"
                if el.find("border") is not None and el.find("width") is None:
                    raise MapError(f"map file {path}: {where} gives its shape by <border>, "
                                   "which is not supported (use <width>)")
                w = _poly(_records(el.findall("width"), "sOffset", path, where), ss - s0,
                          end=s1 - s0)
                w = np.maximum(w, 0.0)
                t = base + sign * (inner + w / 2)
                inner = inner + w
                cx, cy = x + t * nx, y + t * ny
                kind = el.get("type", "none")
                forward = (lid < 0) != lht
                if kind == "bidirectional":
                    forward = lid < 0
                pts = np.stack([cx, cy], axis=1)
                wid, rh = w, h
                if not forward:
                    pts, wid, rh = pts[::-1], wid[::-1], h[::-1] + np.pi
                if not (np.isfinite(pts).all() and np.isfinite(wid).all()):
                    raise MapError(f"map file {path}: {where}'s centre line is not finite (its "
                                   "road's geometry or its <width>/<laneOffset> overflows)")
                seg = np.hypot(*np.diff(pts, axis=0).T)
                s_lane = np.concatenate([[0.0], np.cumsum(seg)])
                keep = np.concatenate([[True], np.diff(s_lane) > 0])
                if not keep.all():  # samples that coincide (a degenerate geometry): one of each
                    pts, wid, rh, s_lane = pts[keep], wid[keep], rh[keep], s_lane[keep]
                if s_lane[-1] < 1e-3:
                    continue  # a lane of no length (a lane that is a point on a tight curve)
                head = _headings(pts)
                sp = _speed(el.find("speed"), path, where)
                lane = LaneData(f"{rid}/{k}/{lid}", rid, k, lid, kind, forward, junction, s_lane,
                                pts, head, wid, rh, sp if math.isfinite(sp) else road_speed)
                lanes[lane.id] = lane
                made.append((lid, lane, el))
        out.append((sec, made))
    return out


def _links(path: str, root: Any, raw: dict, lanes: dict) -> dict:
    """Successors ("out") and predecessors ("in") of every lane, in the direction of travel."""
    ends: dict[tuple[str, str], set] = {}  # (lane id, "start"/"end" along the reference) -> ends

    def ref_end(lane: LaneData, which: str) -> np.ndarray:
        # the lane's point at the reference line's start/end of its section
        at_start = (which == "start") == lane.forward
        return lane.xy[0] if at_start else lane.xy[-1]

    def connect(a: str, ea: str, b: str, eb: str) -> None:
        if a not in lanes or b not in lanes:
            return
        gap = float(np.hypot(*(ref_end(lanes[a], ea) - ref_end(lanes[b], eb))))
        if gap > 1.0:
            return  # a link the geometry does not carry out; routes would jump
        ends.setdefault((a, ea), set()).add((b, eb))
        ends.setdefault((b, eb), set()).add((a, ea))

    def section_lanes(rid: str, which: str) -> tuple[int, dict[int, Any]]:
        secs = raw[rid][1]
        k = 0 if which == "start" else len(secs) - 1
        while 0 <= k < len(secs) and not secs[k][1]:
            k += 1 if which == "start" else -1
        k = min(max(k, 0), len(secs) - 1)
        return k, {lid: el for lid, _, el in secs[k][1]}

    for rid, (road, secs) in raw.items():
        for k, (sec, made) in enumerate(secs):
            nxt = next((j for j in range(k + 1, len(secs)) if secs[j][1]), None)
            for lid, lane, el in made:
                if nxt is not None:
                    for s_el in el.findall("link/successor"):
                        connect(lane.id, "end", f"{rid}/{nxt}/{s_el.get('id')}", "start")
                prv = next((j for j in range(k - 1, -1, -1) if secs[j][1]), None)
                if prv is not None:
                    for p_el in el.findall("link/predecessor"):
                        connect(lane.id, "start", f"{rid}/{prv}/{p_el.get('id')}", "end")
        for tag, which in (("successor", "end"), ("predecessor", "start")):
            link = road.find(f"link/{tag}")
            if link is None or link.get("elementType", "road") != "road":
                continue
            other = link.get("elementId", "")
            if other not in raw:
                continue
            cp = link.get("contactPoint", "start")
            k, mine = section_lanes(rid, which)
            ok, theirs = section_lanes(other, cp)
            for lid, el in mine.items():
                for l_el in el.findall(f"link/{tag}"):
                    connect(f"{rid}/{k}/{lid}", which, f"{other}/{ok}/{l_el.get('id')}", cp)
    for junction in root.findall("junction"):
        for con in junction.findall("connection"):
            inc, via = con.get("incomingRoad", ""), con.get("connectingRoad", "")
            if inc not in raw or via not in raw:
                continue
            cp = con.get("contactPoint", "start")
            jid = junction.get("id")
            inc_road = raw[inc][0]
            which = None
            for tag, w in (("successor", "end"), ("predecessor", "start")):
                l = inc_road.find(f"link/{tag}")
                if l is not None and l.get("elementType") == "junction" and l.get("elementId") == jid:
                    which = w if which is None else "both"
            k_via, _ = section_lanes(via, cp)
            for ll in con.findall("laneLink"):
                for w in (("start", "end") if which in (None, "both") else (which,)):
                    k_inc, _ = section_lanes(inc, w)
                    connect(f"{inc}/{k_inc}/{ll.get('from')}", w, f"{via}/{k_via}/{ll.get('to')}", cp)
    out: dict[tuple[str, str], set] = {}
    for (a, ea), others in ends.items():
        la = lanes[a]
        a_exit = "end" if la.forward else "start"
        for b, eb in others:
            lb = lanes[b]
            b_entry = "start" if lb.forward else "end"
            if ea == a_exit and eb == b_entry:
                out.setdefault((a, "out"), set()).add(b)
                out.setdefault((b, "in"), set()).add(a)
    return out


# -- a parameter over a map's lanes ---------------------------------------------------------------------


def default_successor(lane: LaneData, lanes: Any) -> LaneData | None:
    """The lane traffic on ``lane`` drives on into when it goes straight on: of its drivable
    successors (looked up in ``lanes``, id -> :class:`LaneData`), the one that turns least
    (then the first by id); None where it has none (the map ends there for traffic)."""
    nxt = [lanes[i] for i in lane.successors if i in lanes and lanes[i].kind in DRIVABLE]
    if not nxt:
        return None
    h0 = float(lane.heading[-1])

    def turn(b: LaneData) -> float:
        h1 = float(b.heading[-1])
        return abs(math.atan2(math.sin(h1 - h0), math.cos(h1 - h0)))

    return min(nxt, key=lambda b: (turn(b), b.id))


def route_end(data: MapData, lane_id: str, need: float) -> tuple[float, str] | None:
    """Where the default route from the start of ``lane_id`` (straight on through junctions,
    as ``MapRoad.default_route`` drives it) ends, when that is less than ``need`` [m] on:
    ``(metres run, id of the lane that has no successor)``; None when it runs ``need`` m (or
    comes back on itself)."""
    lane = data.lanes[lane_id]
    run = 0.0
    seen = set()
    while True:
        run += lane.length
        if run >= need or lane.id in seen:
            return None
        seen.add(lane.id)
        nxt = default_successor(lane, data.lanes)
        if nxt is None:
            return run, lane.id
        lane = nxt


def why_no_successor(data: MapData, lane_id: str) -> str:
    """Why the file gives lane ``lane_id`` no drivable successor, naming the element: the
    road's ``<link>`` has none (the map's edge), it names a road or junction the file lacks,
    the lane's own ``<link>`` is missing or names a lane that is not there, the successor is
    not a driving lane, or the two do not meet. Reads the file again (an error path)."""
    lane = data.lanes[lane_id]
    tag = "successor" if lane.forward else "predecessor"
    where = f"road {lane.road} lane {lane.lane}"
    for other in lane.successors:
        o = data.lanes.get(other)
        if o is not None and o.kind not in DRIVABLE:
            return f"{where}'s {tag} {other} is a {o.kind} lane, not one to drive on"
    try:
        from lxml import etree as ET

        root = ET.fromstring(Path(data.path).read_bytes(), parser=ET.XMLParser(huge_tree=True))
    except Exception:  # noqa: BLE001 - only an explanation: the file changed or went away
        return f"{where} has no {tag} in the file's links"
    roads = {r.get("id", ""): r for r in root.findall("road")}
    road = roads.get(lane.road)
    sections = road.findall("lanes/laneSection") if road is not None else []
    last = len(sections) - 1 if lane.forward else 0
    lane_el = None
    if 0 <= lane.section < len(sections):
        for el in sections[lane.section].iter("lane"):
            if el.get("id") == str(lane.lane):
                lane_el = el
    own = lane_el.find(f"link/{tag}") if lane_el is not None else None

    def named(target: str) -> str:
        # what is wrong with the lane a link names
        t = data.lanes.get(target)
        if t is None:
            return "a lane the file lacks there"
        gap = float(np.hypot(*(lane.xy[-1] - t.xy[0])))
        if gap > 1.0:
            return (f"lane {target}, which starts {gap:.1f} m from this lane's end (links "
                    "whose lanes do not meet within 1 m are not followed)")
        return f"lane {target}, which runs the other way"

    if lane.section != last:
        if own is None:
            return (f"{where} in lane section {lane.section} has no <link><{tag}> into the "
                    "next lane section")
        nxt = lane.section + (1 if lane.forward else -1)
        return (f"{where}'s <link><{tag} id='{own.get('id')}'> names "
                + named(f"{lane.road}/{nxt}/{own.get('id')}"))
    link = road.find(f"link/{tag}") if road is not None else None
    if link is None:
        return f"road {lane.road}'s <link> has no <{tag}>: the map ends there"
    kind, eid = link.get("elementType", "road"), link.get("elementId", "")
    if kind == "junction":
        junction = next((j for j in root.findall("junction") if j.get("id") == eid), None)
        if junction is None:
            return (f"road {lane.road}'s <link><{tag} elementType='junction' elementId='{eid}'> "
                    "names a junction the file lacks")
        froms = [ll for c in junction.findall("connection") if c.get("incomingRoad") == lane.road
                 for ll in c.findall("laneLink") if ll.get("from") == str(lane.lane)]
        if not froms:
            return (f"junction {eid} has no <connection incomingRoad='{lane.road}'> with a "
                    f"<laneLink from='{lane.lane}'>")
        return (f"junction {eid}'s <laneLink from='{lane.lane}'> of road {lane.road} leads to a "
                "lane that is missing or does not meet this one's end")
    if eid not in roads:
        return (f"road {lane.road}'s <link><{tag} elementType='road' elementId='{eid}'> names a "
                "road the file lacks")
    if own is None:
        return f"{where} has no <link><{tag}> into road {eid}"
    theirs = roads[eid].findall("lanes/laneSection")
    k = 0 if link.get("contactPoint", "start") == "start" else len(theirs) - 1
    return (f"{where}'s <link><{tag} id='{own.get('id')}'> into road {eid} names "
            + named(f"{eid}/{k}/{own.get('id')}"))


class MapLane(Choice):
    """A categorical parameter over the lanes of a map file, read at collection::

        @scenario(lane=MapLane("maps/Town06.xodr", kind="driving", min_length=100))

    Its values are lane ids (``"road/section/lane"``); samplers stratify over them, shrinking
    moves toward the first, and coverage counts them as a categorical parameter. A relative
    ``path`` is looked up from the declaring test module's folder, then the working
    directory. ``kind`` is a lane type or a list of them (None: every lane); ``min_length``
    [m] drops shorter lanes; ``junctions`` False (the default) leaves out lanes inside
    junctions. ``ahead`` [m] is the road the scenario needs straight on from the start of the
    lane (the map's default route through junctions, as ``town.ahead`` and the drivers follow
    it): lanes whose route ends sooner, at a lane with no successor, are left out; when none
    is left, the collection error names the file, the lane where each route ends and why the
    file gives it no successor. Its description is the plain ``Choice`` over the ids, so
    stored cases replay without the file.
    """

    def _setup(self, path: Any, kind: Any = "driving", min_length: float = 0.0,
               junctions: bool = False, ahead: float = 0.0) -> None:
        try:
            data = load(path, base=_declaring_dir())
        except MapError as exc:
            raise SpaceError(str(exc)) from None
        call = f"MapLane({os.fspath(path)!r}, kind={kind!r}, min_length={min_length!r}"
        try:
            need = float(ahead)
        except (TypeError, ValueError):
            need = math.nan
        if not math.isfinite(need) or need < 0:
            raise SpaceError(f"{call}, ahead={ahead!r}): ahead is the road [m] the scenario "
                             "needs straight on from the lane's start, a finite number >= 0")
        ids = [l.id for l in data.of_kind(kind, float(min_length))
               if junctions or not l.junction]
        if not ids:
            raise SpaceError(f"{call}): no lane of the map matches")
        if need > 0:
            ends = {i: route_end(data, i, need) for i in ids}
            ids = [i for i in ids if ends[i] is None]
            if not ids:
                # a route needs a successor the map does not give: say where and why
                by_end: dict[str, list[tuple[float, str]]] = {}
                for i, (run, last) in ends.items():
                    by_end.setdefault(last, []).append((run, i))
                shown = sorted(by_end.items(), key=lambda kv: -max(r for r, _ in kv[1]))[:3]
                parts = [f"from {max(v)[1]} the route ends {max(v)[0]:.0f} m on at lane {last}, "
                         f"which has no successor ({why_no_successor(data, last)})"
                         for last, v in shown]
                raise SpaceError(
                    f"{call}, ahead={ahead!r}): map file {data.path}: no matching lane's route "
                    f"runs {need:g} m: " + "; ".join(parts)
                    + (f"; and {len(by_end) - 3} more dead ends" if len(by_end) > 3 else "")
                    + ". Ask for less road ahead, or use a map whose lanes continue there")
        self.map_path = data.path
        super()._setup(ids)


def _declaring_dir() -> Path | None:
    dirs = _caller_dirs()
    return dirs[0] if dirs else None
