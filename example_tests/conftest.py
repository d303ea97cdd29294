"""Settings of the example suite.

The showcase runs 1,320 cases (11 scenario tests x 2 samplers x 60); about 40 % of them fail
by design. Minimizing every failure (default 20 simulations plus a PNG and a GIF each) would
take the suite from ~5 minutes to over 30 on 2 cores, so here shrinking is off unless asked
for: ``--avs-shrink-budget 10`` (or ini ``avs_shrink_budget``) turns it back on, e.g. for one
scenario with ``-k``.
"""


def pytest_configure(config):
    try:
        given = config.getoption("avs_shrink_budget")
    except ValueError:  # the plugin is disabled (-p no:avscenario)
        return
    if given is None and not config.getini("avs_shrink_budget"):
        config.option.avs_shrink_budget = 0
