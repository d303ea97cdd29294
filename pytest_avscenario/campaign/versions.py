"""The versions a run and its stored counterexamples were made with."""

from __future__ import annotations


def versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("pytest-avscenario", "highway-env"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "not installed"
    return out
