"""Where a scenario case is simulated: in this process (default) or on a Dask cluster.

The plugin asks its executor for the outcome of every case — the sampled one, and each
candidate while shrinking — through one small interface (:class:`Executor`). Executors know
pytest items only as the plain :class:`CaseJob` the plugin hands them.
"""

from typing import Any

from .base import CaseJob, Executor, InProcessExecutor

__all__ = ["CaseJob", "Executor", "InProcessExecutor", "make_executor"]


def make_executor(name: str, **options: Any) -> Executor:
    """The executor called ``name`` (``inprocess``, ``dask``); ValueError names the options."""
    if name in (None, "", "inprocess"):
        return InProcessExecutor()
    if name == "dask":
        try:
            from .dask import DaskExecutor
        except ImportError as exc:
            raise ValueError(
                f"--avs-executor=dask needs Dask: pip install 'pytest-avscenario[dask]' ({exc})"
            ) from None
        return DaskExecutor(**options)
    raise ValueError(f"unknown executor {name!r}; available: inprocess, dask")
