"""The warp core against an older version of itself, interleaved in one process.

    python -m bench.warp_compare [--base REV] [--boxes N] [--repeat R] [--json]

``make bench``'s frames (``bench.warp_speed``: a new View and Light, B, then
the method) for every method, the sun, the point and the spot light, timed for
the working tree's ``addon/warp`` and for ``addon/warp`` as it was at ``REV``
(extracted with ``git archive`` and imported under another package name). The
two run in alternating rounds in the same process, so the machine's drift
(other processes, clock changes) falls on both alike; each figure is the
median over the rounds of the mean CPU time of the thread per call, and the
ratio is new / old.
Run it with one BLAS thread, as ``make bench`` does:

    OPENBLAS_NUM_THREADS=1 python -m bench.warp_compare
"""
from __future__ import annotations

import argparse
import importlib.util
import io
import json
import math
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASE = "86afed0"
"""The "before" of issue 16's speed criterion: main just before the warp-core changes (77dd852) with
the linear depth rows that landed while they were made (the depth helper's commits as first written
on 77dd852, linear_z on by default), so both sides compute the same maps."""


def load_package(rev: str, name: str = "lixel_base_warp"):
    """``addon/warp`` as it was at ``rev``, imported as the package ``name``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "addon/warp"], check=True,
                             capture_output=True).stdout
    where = Path(tempfile.mkdtemp(prefix="lixel-warp-")) / rev
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(where, filter="data")
    package = where / "addon" / "warp"
    spec = importlib.util.spec_from_file_location(name, package / "__init__.py",
                                                  submodule_search_locations=[str(package)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def frames(warp, boxes: np.ndarray) -> dict:
    """{(light, method): a whole frame} for one version of the warp core
    (``method`` "B": the intersection body alone)."""
    from bench.warp_speed import EYE, FOV_Y, LIGHT_PARAMETERS, TARGET, new_frame
    look_along = importlib.import_module(warp.__name__ + ".geometry").look_along
    scene = warp.SceneBounds.from_boxes(boxes)
    cam_to_world = np.linalg.inv(look_along(EYE, TARGET - EYE, [0.0, 0.0, 1.0]))
    view = warp.View.perspective(cam_to_world, FOV_Y, 16 / 9, 0.1, 150.0, (1920, 1080))
    options = warp.WarpOptions(shadow_map_size=(2048, 2048))
    out = {}
    for lname, params in LIGHT_PARAMETERS.items():
        light = warp.Light(**params)

        def body_only(light=light):
            return warp.intersection_body(*new_frame(view, light), scene)

        out[(lname, "B")] = body_only
        for mname, method in warp.METHODS.items():
            def frame(light=light, method=method):
                v, l = new_frame(view, light)
                return method(v, l, warp.intersection_body(v, l, scene), options)
            out[(lname, mname)] = frame
    return out


def timed(fn, loops: int) -> float:
    """Seconds of this thread's CPU time per call (time other processes take
    from a shared machine's cores is not counted; wall time would be)."""
    t0 = time.thread_time()
    for _ in range(loops):
        fn()
    return (time.thread_time() - t0) / loops


def compare(old: dict, new: dict, repeat: int, budget_s: float = 0.005) -> dict:
    """(old µs, new µs, new / old) per frame: medians over ``repeat`` rounds,
    old and new alternating (and which goes first alternating too)."""
    out = {}
    for key in new:
        if key not in old:
            continue
        fo, fn = old[key], new[key]
        try:
            fo(), fn()
        except Exception:                    # (a method that needs more than B, e.g. the cascade, is skipped)
            continue
        loops = max(1, int(budget_s / max(timed(fo, 1), timed(fn, 1), 1e-7)))
        times = {"old": [], "new": []}
        for r in range(repeat):
            order = (("old", fo), ("new", fn)) if r % 2 == 0 else (("new", fn), ("old", fo))
            for side, f in order:
                times[side].append(timed(f, loops))
        a, b = float(np.median(times["old"])) * 1e6, float(np.median(times["new"])) * 1e6
        out[key] = (a, b, b / a)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.warp_compare", description=__doc__.splitlines()[0])
    ap.add_argument("--base", default=BASE, help=f"the old version (a git revision; default {BASE})")
    ap.add_argument("--boxes", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=31)
    ap.add_argument("--only", help="comma-separated frames to time (B, a method name), default all")
    ap.add_argument("--lights", default="sun,point,spot", help="comma-separated lights (default sun,point,spot)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from bench.warp_speed import city_boxes
    import addon.warp as current
    boxes = city_boxes(args.boxes)
    new = {(l, m): f for (l, m), f in frames(current, boxes).items()
           if l in args.lights.split(",") and (not args.only or m in args.only.split(","))}
    res = compare(frames(load_package(args.base), boxes), new, args.repeat)
    if args.json:
        json.dump({f"{l}/{m}": v for (l, m), v in res.items()}, sys.stdout, indent=1)
        print()
        return 0
    print(f"warp core: working tree against {args.base}, {args.boxes} boxes, µs per frame "
          f"(median of {args.repeat} interleaved rounds), new / old")
    methods = list(dict.fromkeys(m for _, m in res))
    for lname in dict.fromkeys(l for l, _ in res):
        print(f"{lname}:")
        for m in methods:
            if (lname, m) in res:
                a, b, r = res[(lname, m)]
                print(f"  {m:<14} {a:8.0f} -> {b:8.0f}   x{r:.3f}")
    worst = max(res.items(), key=lambda kv: kv[1][2] if math.isfinite(kv[1][2]) else 0)
    print(f"largest ratio: {worst[0][0]} {worst[0][1]} x{worst[1][2]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
