"""The ``@scenario`` decorator, ``@example`` pins, and the spec they store on a test.

``@scenario(...)`` returns a ``pytest.mark.scenario`` mark carrying a :class:`ScenarioSpec`.
Nothing is validated here: a declaration error is raised by the plugin at collection, where
it can name the test. That keeps decorating cheap and keeps every error message in one place.
"""

from .spec import ScenarioSpec, example, scenario

__all__ = ["ScenarioSpec", "example", "scenario"]
