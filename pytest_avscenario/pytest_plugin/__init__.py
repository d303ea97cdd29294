"""The pytest side of pytest-avscenario: the only package that imports pytest, adapters to
the campaign engine (:mod:`pytest_avscenario.campaign`).

``hooks`` (the entry point: hooks and fixtures, nothing else), ``options`` (the command line
and ini file read into one frozen settings object per session), ``collect`` (the checks only
collection can make; one item per case slot), ``items`` (a pytest item as a campaign case, its
row on its reports), ``session`` (the one session object: campaigns, executor, report sink),
``controller`` (the error table, the xdist merge and the end-of-run report), ``stopping``
(signals, ``os._exit``, stuck cases), ``identity`` (the session's driver), ``stash`` (the
``pytest.StashKey`` s), ``newhooks`` (the hookspecs a conftest.py implements). Everything
below this package — campaign, space, samplers, monitors, sim, shrink, db, report, executors —
knows nothing of pytest.
"""
