"""Scout a scenario module outside pytest: run its nominal case and sampled ones, print the
robustness of every metric, and render frames to look at.

It is what the example scenarios were tuned with (and how ``frames/`` was made)::

    python example_tests/scout.py test_02_vehicle_following -n 30            # nominal + 30 Halton
    python example_tests/scout.py test_06_pedestrian_crossing --driver idm -n 30
    python example_tests/scout.py test_05_encroaching_oncoming_car --png frames/05.png
    python example_tests/scout.py test_07_oncoming_left_turn --params '{"d_ego": 20}' \
        --png /tmp/x.png
    python example_tests/scout.py --frames          # re-render frames/ (nominal cases)

Cases are built the way the plugin builds them (``Case`` + ``World`` with the case's seed and
rng), so a row here replays under pytest with ``--avs-params``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))

#: fixed views [m] (centre x, centre y, width) for frames/ where following the ego hides the action
FRAME_VIEWS = {
    "test_03_parallel_parking": "122,-2,50",
    "test_06_pedestrian_crossing": "112,0,60",
    "test_maps_fabriksgatan_left_turn": "22,-6,70",
    "test_maps_town06_red_light": "140,16,100",
}


def scenario_tests(module):
    """``(name, function, spec)`` of every @scenario test of a module."""
    out = []
    for name in dir(module):
        fn = getattr(module, name)
        if not (name.startswith("test") and callable(fn)):
            continue
        for mark in getattr(fn, "pytestmark", []):
            if mark.name == "scenario":
                out.append((name, fn, mark.args[0]))
    return out


def run_one(fn, spec, params, seed, driver, png=None, gif=None, width=1280, view=None):
    from pytest_avscenario import Case
    from pytest_avscenario.monitors import MonitorSet
    from pytest_avscenario.sim import World

    case = Case(params, index=0, seed=seed, sampler="scout", test=fn.__name__)
    world = World(seed=case.seed, rng=case.rng, driver=driver, name=fn.__name__)
    t0 = time.perf_counter()
    error = None
    try:
        fn(case=case, world=world)
    except AssertionError as exc:
        error = f"assert: {exc}"
    wall = time.perf_counter() - t0
    traj = world.trajectory
    verdict = MonitorSet(list(spec.monitors), priority=spec.priority).evaluate(traj)
    if png:
        world.render_png(png, **(view or {}))
        if width:
            _shrink(png, width)
    if gif:
        world.render_gif(gif, every=2)
    return verdict, wall, error, world


def _shrink(path, width=1280):
    """Downscale and quantize a PNG so the kept frames stay a few tens of KB."""
    from PIL import Image

    im = Image.open(path).convert("RGB")
    if im.width > width:
        im = im.resize((width, round(im.height * width / im.width)), Image.LANCZOS)
    im = im.quantize(colors=32)
    im.save(path, optimize=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("module", nargs="?")
    ap.add_argument("--frames", action="store_true",
                    help="render the nominal case of every module into frames/")
    ap.add_argument("-n", type=int, default=0, help="Halton samples after the nominal case")
    ap.add_argument("--sampler", default="halton")
    ap.add_argument("--driver", default="autopilot")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--params", default=None, help="JSON overriding nominal values")
    ap.add_argument("--png", default=None, help="render the (first) case to this PNG")
    ap.add_argument("--gif", default=None)
    ap.add_argument("--width", type=int, default=1280, help="downscale PNGs to this width [px]")
    ap.add_argument("--view", default=None,
                    help="fixed view 'x,y,width' [m] for the PNG (default: follow the ego)")
    ap.add_argument("--render-failures", default=None, help="directory: PNG of each failure")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if args.frames:
        for name in sorted(f[:-3] for f in os.listdir(HERE)
                           if f.startswith("test_") and f.endswith(".py")
                           and (f[5:7].isdigit() or f.startswith(("test_r157_", "test_maps_")))):
            out = os.path.join(HERE, "frames", name.removeprefix("test_") + ".png")
            extra = ["--view", FRAME_VIEWS[name]] if name in FRAME_VIEWS else []
            main([name, "--png", out, "--quiet", "--driver", args.driver, *extra])
        return
    if not args.module:
        ap.error("give a module (e.g. test_02_vehicle_following) or --frames")

    sys.path.insert(0, HERE)
    from pytest_avscenario import samplers
    from pytest_avscenario.case import stable_seed
    from pytest_avscenario.space import FeatureSpace

    view = None
    if args.view:
        x, y, w = (float(v) for v in args.view.split(","))
        view = {"centre": (x, y), "width": w}
    module = importlib.import_module(args.module.removesuffix(".py").split("/")[-1])
    for name, fn, spec in scenario_tests(module):
        space = FeatureSpace(spec.parameters)
        nominal = {**space.nominal(), **json.loads(args.params or "{}")}
        cases = [("nominal", nominal)]
        if args.n:
            s = samplers.make(args.sampler, space, seed=args.seed)
            for k, p in enumerate(s.sample_unit(args.n)):
                cases.append((f"{args.sampler}-{k:03d}", space.from_unit(p)))
        counts = {}
        total = 0.0
        print(f"== {name} ({args.driver})")
        for k, (label, params) in enumerate(cases):
            png = args.png if k == 0 else None
            verdict, wall, error, world = run_one(fn, spec, params, stable_seed(args.seed, label),
                                                  args.driver, png=png,
                                                  gif=args.gif if k == 0 else None,
                                                  width=args.width, view=view)
            total += wall
            bad = verdict.violated
            for m in bad:
                counts[m] = counts.get(m, 0) + 1
            if bad and args.render_failures:
                os.makedirs(args.render_failures, exist_ok=True)
                out = os.path.join(args.render_failures, f"{name}-{label}.png")
                world.render_png(out)
                _shrink(out, args.width)
            if not args.quiet or k == 0 or bad:
                rho = " ".join(f"{m}={v:+.2f}" if math.isfinite(v) else f"{m}={v}"
                               for m, v in verdict.rho.items())
                ps = " ".join(f"{p}={v:.3g}" if isinstance(v, float) else f"{p}={v}"
                              for p, v in params.items())
                crashed = world.trajectory.meta.get("crashed")
                print(f"{label:11s} {'FAIL' if bad else 'ok  '} {rho} | {ps}"
                      f"{' crashed=' + str(crashed) if crashed else ''}"
                      f"{' ' + error if error else ''} [{wall * 1000:.0f} ms]")
        print(f"-- {len(cases)} cases, violations {counts}, "
              f"{total / len(cases) * 1000:.0f} ms/case")


if __name__ == "__main__":
    main()
