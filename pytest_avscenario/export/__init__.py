"""Counterexamples that leave the plugin: OpenSCENARIO + OpenDRIVE, and an OSI trace.

:func:`export_case` writes, for one case whose world has run, ``<stem>.xosc`` (the scenario
in OpenSCENARIO 1.3: :mod:`.openscenario`; ``<stem>.v1_0.xosc`` the same in 1.0, the
revision CARLA's ScenarioRunner reads), ``<stem>.xodr`` (its road: :mod:`.opendrive`; a case
built on a map file references a copy of that map instead, ``<map>-<8 hex>.xodr``, written
once per folder) and an OSI SensorView trace (:mod:`.osi`) beside them, each atomically, and
returns what it wrote. A part that
cannot be written is reported in the result (``errors``), never raised past the caller's
case. :func:`schema_path` finds the XSDs scenariogeneration installs, for validation;
:mod:`.replay` plays an exported file back in the plugin's own simulator.

Nothing here imports pytest; scenariogeneration (the ``[export]`` extra, through
:mod:`._writers`, which defers what writing never uses) and osi3 (the ``[osi]`` extra) are
imported when a file is written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

__all__ = ["ExportResult", "export_case", "schema_path"]


@dataclass
class ExportResult:
    """``files``: kind (``xosc``: OpenSCENARIO 1.3, ``xosc_1_0``: the same in 1.0 for CARLA's
    ScenarioRunner, ``xodr``, ``osi``) -> path written; ``trajectories``: agents
    exported as their recorded trajectories and why; ``errors``: kind -> why it was not written."""

    files: dict[str, str] = field(default_factory=dict)
    actions: dict[str, str] = field(default_factory=dict)
    trajectories: dict[str, str] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # what the road file leaves out

    def to_json(self) -> dict[str, Any]:
        """The row's ``exports`` field: file names (relative to the card's folder), which
        agents follow trajectories, and what failed."""
        out: dict[str, Any] = {k: Path(v).name for k, v in self.files.items()}
        if self.trajectories:
            out["trajectories"] = dict(self.trajectories)
        if self.errors:
            out["errors"] = dict(self.errors)
        if self.notes:
            out["notes"] = list(self.notes)
        return out


def schema_path(name: str = "OpenSCENARIO_1_3_1.xsd") -> Path:
    """The XSD ``name`` that scenariogeneration installs (``OpenSCENARIO_1_3_1.xsd``,
    ``opendrive_17_core.xsd``…); FileNotFoundError when it is not installed."""
    from importlib import metadata

    for f in metadata.files("scenariogeneration") or ():
        if f.name == name:
            return Path(f.locate())
    raise FileNotFoundError(f"scenariogeneration installs no {name}")


def _map_copy(path: Path, directory: Path) -> Path:
    """The map file copied beside the exports as ``<name>-<8 hex of its content>.xodr``:
    written once per folder (every case on that map references the one copy), the same map
    the same name, two maps of one name never in each other's place."""
    import hashlib

    from ..files import atomic_write_bytes

    blob = path.read_bytes()
    target = directory / f"{path.stem}-{hashlib.sha256(blob).hexdigest()[:8]}.xodr"
    if not target.is_file() or target.stat().st_size != len(blob):
        atomic_write_bytes(target, blob, durable=False)
    return target


def export_case(world: Any, params: Mapping[str, Any], directory: str | os.PathLike[str],
                stem: str, *, units: Mapping[str, str] | None = None, title: str = "",
                osi: bool = True) -> ExportResult:
    """Write ``world``'s case (run, with its recording) as ``<directory>/<stem>.xosc`` and
    ``.xodr``, and with ``osi`` its SensorView trace; never raises for a part that fails."""
    from ..files import atomic_write_bytes

    out = ExportResult()
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        from .opendrive import road_xodr
        from .openscenario import scenario_xosc

        road = None
        if getattr(world.road, "kind", "") == "map":  # its map file, once beside the cases
            from .opendrive import map_roadmap

            rmap = map_roadmap(world.road)
            xodr_path = _map_copy(Path(rmap.map_path), directory)
        else:
            try:
                road, rmap = road_xodr(world.road)  # the same road, the same file
            except NotImplementedError as exc:  # the scenario still goes out, without its road
                from .opendrive import RoadMap

                road, rmap = None, RoadMap(kind=str(getattr(world.road, "kind", "")), exact=False)
                rmap.notes.append(f"{exc}: no road file; every agent follows its recorded "
                                  "trajectory in world coordinates")
            xodr_path = directory / f"{stem}.xodr"
            if road is not None:
                atomic_write_bytes(xodr_path, road, durable=False)
        if road is not None or rmap.map_path:
            out.files["xodr"] = str(xodr_path)
        road_file = xodr_path.name if "xodr" in out.files else None
        sce = scenario_xosc(world, params, units=units, road_file=road_file, rmap=rmap,
                            title=stem, description=title or stem)
        xosc_path = directory / f"{stem}.xosc"
        atomic_write_bytes(xosc_path, sce.xml, durable=False)
        out.files["xosc"] = str(xosc_path)
        out.actions, out.trajectories, out.notes = sce.actions, sce.trajectories, sce.notes
    except Exception as exc:  # an export is extra evidence: say why, keep the case
        out.errors["xosc"] = f"{type(exc).__name__}: {exc}"
    if "xosc" in out.files:
        try:  # CARLA's ScenarioRunner reads OpenSCENARIO 1.0 only
            old = scenario_xosc(world, params, units=units, road_file=road_file,
                                rmap=rmap, title=stem, description=title or stem, minor=0)
            path = directory / f"{stem}.v1_0.xosc"
            atomic_write_bytes(path, old.xml, durable=False)
            out.files["xosc_1_0"] = str(path)
            for name, why in old.trajectories.items():
                if name not in out.trajectories:
                    out.trajectories[name] = f"in the 1.0 file only: {why}"
        except Exception as exc:
            out.errors["xosc_1_0"] = f"{type(exc).__name__}: {exc}"
    if osi:
        try:
            from .osi import trace_bytes, trace_name

            data, frames = trace_bytes(world)
            path = directory / trace_name(frames, stem)
            atomic_write_bytes(path, data, durable=False)
            out.files["osi"] = str(path)
        except Exception as exc:
            out.errors["osi"] = f"{type(exc).__name__}: {exc}"
    return out
