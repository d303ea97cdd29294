"""Settings of the example suite.

The showcase runs 1,560 cases (11 scenario tests x 2 samplers x 60 and 4 highway tests x 2
samplers x 30), and about half of them fail by design. Two of the plugin's per-failure extras
would dominate its run time on 2 cores:

* minimizing every failure (default 20 simulations each) takes the suite from under 2 minutes
  to over 30;
* a GIF of a failing run costs ~2 s of CPU (a PNG of its first violation 0.1-0.3 s), and the
  default cap of 3 GIFs per test and worker adds ~2.5 minutes of CPU — most of the 5-sample
  quick mode's time.

So here only the first failure of each scenario test and sampler is minimized (and stored
for replay, with its ``@example`` line), and no GIFs are drawn, unless the command line or an
ini file says otherwise: ``--avs-shrink-max 10 --avs-gifs 3`` (e.g. for one scenario with
``-k``). Every failing case still gets its card in the report, and the PNG of its first
violation for the minimized ones and the first ``--avs-case-pictures`` (5) per test and sampler.
"""

_SUITE_DEFAULTS = {"avs_shrink_max": 1, "avs_gifs": 0}


def pytest_configure(config):
    for name, value in _SUITE_DEFAULTS.items():
        try:
            given = config.getoption(name)
            in_ini = config.getini(name)
        except ValueError:  # the plugin is disabled (-p no:avscenario) or predates the option
            continue
        if given is None and not in_ini:
            setattr(config.option, name, value)
