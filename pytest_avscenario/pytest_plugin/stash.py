"""What the plugin keeps per pytest config and per item: ``pytest.StashKey``s, no globals."""

from __future__ import annotations

from typing import Any

import pytest

settings_key = pytest.StashKey[Any]()  # the session's options.Settings
plans_key = pytest.StashKey[dict]()  # function node id -> campaign.plan.ScenarioPlan (frozen)
campaigns_key = pytest.StashKey[dict]()  # function node id -> campaign.state.Campaign (running state)
session_key = pytest.StashKey[Any]()  # the session.ScenarioSession
db_key = pytest.StashKey[Any]()  # the ReplayDB, or None
executor_key = pytest.StashKey[Any]()  # the Executor, made on first use
controller_key = pytest.StashKey[Any]()  # the controller.RunState
case_item_key = pytest.StashKey[Any]()  # item -> its items.PytestCase (the campaign's view)
row_key = pytest.StashKey[Any]()  # item -> its error-table row (outcome.CaseRow)
shrink_rows_key = pytest.StashKey[list]()  # item -> its shrinking candidates' rows
pictures_key = pytest.StashKey[dict]()  # item -> {caption: picture path}
result_key = pytest.StashKey[Any]()  # item -> its campaign.pipeline.ItemResult (set during setup)
sent_key = pytest.StashKey[bool]()  # item -> its row went out with a report already
told_key = pytest.StashKey[set]()  # tests whose declaration (plan.info) went out with a report
guard_key = pytest.StashKey[Any]()  # the stopping.TermGuard of this process
sentinel_key = pytest.StashKey[Any]()  # the lastresort.Sentinel of this process (made on first use)
driver_key = pytest.StashKey[Any]()  # the identity of the --avs-driver driver (a dict)
let_go_key = pytest.StashKey[list]()  # workers an interrupted xdist controller let exit early (stopping)
