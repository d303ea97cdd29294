"""``python -m pytest_avscenario.stack [ADDRESS] [--driver NAME] [--answer KIND]``: serve a driver over avs-osi/1.

ADDRESS defaults to ``$AVS_OSI_ADDRESS`` (what ``--avs-driver osi+spawn:COMMAND`` sets);
NAME to the built-in autopilot (any driver name the plugin accepts: ``careful``,
``package.module:Name``).
"""

from __future__ import annotations

import argparse
import os
import sys


def main(argv: list[str] | None = None, default_driver: str = "autopilot") -> int:
    from .kit import serve

    p = argparse.ArgumentParser(prog="python -m pytest_avscenario.stack", description=__doc__.split("\n")[0])
    p.add_argument("address", nargs="?", default=os.environ.get("AVS_OSI_ADDRESS"),
                   help="tcp://HOST:PORT or ipc://PATH to bind (default $AVS_OSI_ADDRESS)")
    p.add_argument("--driver", default=default_driver, help=f"driver to serve (default {default_driver})")
    p.add_argument("--answer", default="desired_state", choices=["desired_state", "trajectory"],
                   help="the MotionRequest sent: a desired state one step ahead (default) or a "
                        "desired trajectory")
    p.add_argument("--spin", type=float, default=None, metavar="US",
                   help="microseconds each wait for a request keeps the CPU before it blocks "
                        "(default $AVS_OSI_SPIN_US, which --avs-driver osi+spawn: sets, else 0)")
    args = p.parse_args(argv)
    if args.spin is not None and not 0 <= args.spin < float("inf"):
        p.error(f"--spin {args.spin:g}: a number of microseconds >= 0")
    if not args.address:
        p.error("give an ADDRESS or set AVS_OSI_ADDRESS")
    serve(args.driver, args.address, answer=args.answer, spin_us=args.spin)
    return 0


if __name__ == "__main__":
    sys.exit(main())
