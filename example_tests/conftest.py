"""Settings of the example suite.

The showcase runs 1,320 cases (11 scenario tests x 2 samplers x 60), and about half of them
fail by design. Two of the plugin's per-failure extras would dominate its run time on 2 cores:

* minimizing every failure (default 20 simulations each) takes the suite from ~5 minutes to
  over 30;
* a GIF of a failing run costs ~2 s of CPU (a PNG of its worst moment 0.1-0.3 s), and the
  default cap of 3 GIFs per test and worker adds ~2.5 minutes of CPU — most of the 5-sample
  quick mode's time.

So here both are off unless asked for on the command line or in an ini file:
``--avs-shrink-budget 10`` and ``--avs-gifs 3`` turn them back on (e.g. for one scenario with
``-k``). Every failing case still gets the PNG of its worst moment in the report.
"""

_SUITE_DEFAULTS = {"avs_shrink_budget": 0, "avs_gifs": 0}


def pytest_configure(config):
    for name, value in _SUITE_DEFAULTS.items():
        try:
            given = config.getoption(name)
            in_ini = config.getini(name)
        except ValueError:  # the plugin is disabled (-p no:avscenario) or predates the option
            continue
        if given is None and not in_ini:
            setattr(config.option, name, value)
