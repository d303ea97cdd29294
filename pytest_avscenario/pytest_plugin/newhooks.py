"""The plugin's own hookspecs: what a team adds in its ``conftest.py`` without private imports.

Registered by :func:`~pytest_avscenario.pytest_plugin.hooks.pytest_addhooks` (pytest-xdist's
``newhooks.py`` pattern). Each hook says where it runs under pytest-xdist: *workers* are the
processes that collect and run items (the single pytest process without xdist); the
*controller* is the process that merges the rows and writes the report (again the single
process without xdist). A conftest.py is loaded in both, so an implementation just works.
"""

from __future__ import annotations

from typing import Any

import pytest


@pytest.hookspec(firstresult=True)
def pytest_avscenario_make_sampler(config: pytest.Config, name: str, space: Any, seed: int,
                                   options: dict[str, Any]) -> Any:
    """Make the sampler named ``name`` for one scenario test, or return None to leave it to
    the built-in registry.

    ``space``: the test's :class:`~pytest_avscenario.FeatureSpace`; ``seed``: the sampler's
    stable seed (derived from the run's seed and ``name``: use it for bit-identical cases in
    every process); ``options``: the test's ``sampler_options``. Return an object with the
    :class:`~pytest_avscenario.samplers.Sampler` protocol (``active``; ``sample_unit(n)`` for a
    passive sampler, ``ask()`` / ``tell(x, rho)`` for an active one) — subclassing
    ``pytest_avscenario.samplers.Sampler`` gives the rest. The name must be one the registry
    knows: a built-in one (to replace how it is made) or one added with
    ``pytest_avscenario.samplers.register``.

    Runs where items are collected: on every xdist *worker* (each makes the same sampler
    from the same seed, so all collect the same items), and again on the worker that runs an
    active sampler's cases.
    """


def pytest_avscenario_case_finished(config: pytest.Config, row: Any) -> None:
    """A scenario case has its row: ``row`` is the frozen
    :class:`~pytest_avscenario.outcome.CaseRow` the error table writes (parameters, every ρ,
    verdict, timing, where it violated first). For a row sink (a database, a dashboard, a
    message queue). Shrink candidates (``row.origin == "shrink"``) are passed too; most sinks
    skip them.

    Runs on the xdist *controller*, once per row, in the order rows arrive (the order cases
    finish); without xdist, in the pytest process right after the case.
    """


def pytest_avscenario_card_sections(config: pytest.Config, row: Any) -> list[tuple[str, str]] | None:
    """Sections to add to the card page of counterexample ``row`` (a
    :class:`~pytest_avscenario.outcome.CaseRow`): a list of ``(title, html)``. The title is
    escaped; the ``html`` is inserted as given (escape your own values, e.g. with
    ``html.escape``). Sections of every implementation appear at the end of the card, after
    the pictures, in plugin order.

    Runs on the xdist *controller* (or the single process) when the report is written, at the
    end of the session; only with ``--avs-report``.
    """


def pytest_avscenario_campaign_verdict(config: pytest.Config, test: str, sampler: str,
                                       rows: list[Any]) -> list[str] | None:
    """Reasons to reject the campaign of ``sampler`` in scenario test ``test`` beyond its
    declared acceptance criteria, or None / ``[]`` to add none. ``rows``: the campaign's
    :class:`~pytest_avscenario.outcome.CaseRow` s (shrink candidates excluded). A rejected
    campaign is listed as REJECTED with these reasons in the terminal, ``summary.json`` and
    the JUnit suite properties, and fails the run, as a declared criterion does.

    Runs on the xdist *controller* (or the single process) at the end of the session, per
    (test, sampler).
    """
