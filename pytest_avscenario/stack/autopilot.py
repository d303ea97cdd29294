"""``python -m pytest_avscenario.stack.autopilot [ADDRESS]``: the built-in autopilot as a stack
out of process (the same decisions as in process; see :mod:`.kit`)."""

import sys

from .__main__ import main

if __name__ == "__main__":
    sys.exit(main(default_driver="autopilot"))
