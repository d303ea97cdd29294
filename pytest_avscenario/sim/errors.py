"""Errors a scenario author can cause in the simulator, and how they read.

Every error names the test (``World.name``), the agent and the offending value, so a failing
case in a 500-case campaign can be traced back to the line of the scenario that produced it.
``SimError`` subclasses ``ValueError`` because it is always about a bad value handed to the
simulator (a position, a duration, a driver's answer), never about the simulator itself.
"""

from __future__ import annotations

__all__ = ["SimError", "DriverError", "SimWarning", "AgentStepWarning", "AgentSpeedWarning"]


class SimError(ValueError):
    """Bad input to the simulator: a placement, a duration, a driver's action.

    ``test`` is the pytest node id of the world (may be ``""``), ``agent`` the agent's name
    (``""`` when the error is not about one agent).
    """

    def __init__(self, message: str, *, test: str = "", agent: str = "") -> None:
        self.test = test
        self.agent = agent
        where = []
        if test:
            where.append(f"in {test}")
        if agent:
            where.append(f"agent {agent!r}")
        prefix = (" ".join(where) + ": ") if where else ""
        super().__init__(prefix + message)


class DriverError(SimError):
    """The driver of the ego raised an exception; ``driver_traceback`` holds its traceback text."""

    def __init__(self, message: str, *, test: str = "", agent: str = "",
                 driver_traceback: str = "") -> None:
        self.driver_traceback = driver_traceback
        if driver_traceback:
            message = f"{message}\n--- driver traceback ---\n{driver_traceback.rstrip()}"
        super().__init__(message, test=test, agent=agent)


class SimWarning(UserWarning):
    """The simulation ran, but not as the scenario or its driver meant; the text says why.

    A ``UserWarning`` (the simulator knows nothing of pytest), so a suite filters it by class:
    ``filterwarnings = ignore::pytest_avscenario.sim.AgentSpeedWarning``.
    """


class AgentStepWarning(SimWarning):
    """A driver that declares its own step (a highway-env agent) ran at another ``dt``."""


class AgentSpeedWarning(SimWarning):
    """The scenario placed the ego at a speed its agent's action type cannot hold."""
