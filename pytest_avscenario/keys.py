"""What the plugin keeps per pytest config and per item (``pytest.StashKey``s, no globals)."""

from __future__ import annotations

from typing import Any

import pytest

plans_key = pytest.StashKey[dict]()  # function node id -> ScenarioPlan
seed_key = pytest.StashKey[int]()  # the run's seed
db_key = pytest.StashKey[Any]()  # the ReplayDB, or None
executor_key = pytest.StashKey[Any]()  # the Executor, made on first use
session_key = pytest.StashKey[Any]()  # the RunState (reporting)
row_key = pytest.StashKey[dict]()  # item -> its error-table row
shrink_rows_key = pytest.StashKey[list]()  # item -> its shrinking candidates' rows
pictures_key = pytest.StashKey[dict]()  # item -> {caption: picture path}
