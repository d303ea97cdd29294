"""Where a scenario case is simulated: in this process (default) or on a Dask cluster.

The plugin asks its executor for the outcome of every case — the sampled one, and each
candidate while shrinking — through one small interface (:class:`Executor`). Executors know
pytest items only as the plain :class:`CaseJob` the plugin hands them.
"""

from .base import CaseJob, Executor, InProcessExecutor, make_executor

__all__ = ["CaseJob", "Executor", "InProcessExecutor", "make_executor"]
