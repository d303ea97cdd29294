"""A counterexample's recording: the clip its card plays and its annotated still shows.

:func:`recording_data` asks the monitors for the run's evidence
(:func:`~pytest_avscenario.monitors.evidence.case_evidence`: the critical agent, the values
toward it, ρ(t) of the violated monitors) and codes it with the run as a clip
(:func:`~pytest_avscenario.sim.clip.clip_data`). The two halves stay apart so the simulator
never imports the monitors or the report; this module is where they meet.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from ..monitors.evidence import case_evidence, critical_hint
from ..sim.clip import CLIP_HZ, clip_data, moment_step
from ..trajectory import Trajectory

__all__ = ["recording_data"]


def recording_data(source: Any, *, violations: Mapping[str, Mapping[str, Any]] | None = None,
                   monitors: Sequence[Any] = (), title: str = "", hz: float = CLIP_HZ,
                   fallback_t: float | None = None, case: str | None = None) -> dict[str, Any]:
    """The recording of one run as plain JSON data (:func:`~pytest_avscenario.sim.clip.clip_data`).

    ``source``: a world after its run, or a Trajectory (then no road is drawn). ``violations``:
    ``{metric: {"t", "agent", "threshold", "rho"}}`` as a case row holds them; the earliest one
    gives the first violation and the critical agent. ``monitors``: the test's monitors, for the
    TTC radius and ρ(t) of the violated ones. ``hz``: frames per second. ``fallback_t`` [s]: the
    moment to start at when nothing says when the violation happened. ``case``: which case the
    run is (``"minimized"``), said beside its numbers.
    """
    traj = source if isinstance(source, Trajectory) else getattr(source, "trajectory", None)
    evidence = None
    if traj is not None:
        moment = moment_step(traj, violations, fallback_t)
        evidence = case_evidence(traj, monitors, agent=critical_hint(violations),
                                 t=float(traj.t[moment]), violated=(violations or {}).keys())
    return clip_data(source, violations=violations, evidence=evidence, title=title, hz=hz,
                     fallback_t=fallback_t, case=case)
