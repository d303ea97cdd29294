"""The pytest side of pytest-avscenario: the only package that imports pytest.

``hooks`` (the entry point: hooks and fixtures, nothing else), ``options`` (one frozen
settings object per session, each value validated once with its source), ``collect`` (a
declaration becomes a frozen plan and one item per case), ``campaign`` (a test's running
state and one item's run), ``failure`` (the failure text and the re-run command),
``controller`` (the error table, the xdist merge and the end-of-run report), ``stash`` (the
``pytest.StashKey`` s), ``newhooks`` (the hookspecs a conftest.py implements). Everything below this package — space, samplers, monitors, sim,
shrink, db, report, executors — knows nothing of pytest.
"""
