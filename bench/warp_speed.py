"""Microseconds per call of the warp core on a 10,000-box scene.

    python -m bench.warp_speed [--boxes N] [--repeat R] [--json]

Times, for a sun, a point light and a spot light, the intersection body B
(``intersection_body``) and a whole frame of every method in ``METHODS`` (``compute``):
B + method, the per-frame cost a renderer pays (the target is < 1 ms in
Python). A method's own cost is the frame's minus B's. Every call gets a new
View and Light, as a moving camera gives, so nothing derived from them (or from
the B of an earlier call) is reused; only the scene's culling index, built once
per scene, is. Each figure is the best over ``repeat`` rounds of the mean time
per call in a round (other processes on a shared machine only ever add time,
so the minimum is the cost of the code; ``--json`` also gives the median).
``make bench`` runs it with one BLAS thread (``OPENBLAS_NUM_THREADS=1``): the
arrays are tiny, and OpenBLAS's idle threads spin on a core, which on a busy
machine costs the calling thread more than the arithmetic.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time

import numpy as np

from addon.warp import METHODS, Light, SceneBounds, View, WarpOptions, compute, intersection_body
from addon.warp.geometry import look_along


def city_boxes(n_boxes: int, seed: int = 7) -> np.ndarray:
    """(n_boxes, 2, 3): a 200 m ground slab plus ``n_boxes - 1`` buildings of random size (deterministic)."""
    rng = np.random.default_rng(seed)
    n = max(n_boxes - 1, 0)
    centre = rng.uniform(-95.0, 95.0, size=(n, 2))
    half = rng.uniform(0.2, 2.0, size=(n, 2))
    height = rng.uniform(0.5, 12.0, size=n)
    lo = np.column_stack([centre - half, np.zeros(n)])
    hi = np.column_stack([centre + half, height])
    ground = np.array([[[-100.0, -100.0, -0.2], [100.0, 100.0, 0.0]]])
    return np.concatenate([ground, np.stack([lo, hi], axis=1)])


def city_scene(n_boxes: int, seed: int = 7) -> SceneBounds:
    """The scene of ``city_boxes``."""
    return SceneBounds.from_boxes(city_boxes(n_boxes, seed))


EYE, TARGET, FOV_Y = np.array([-60.0, -55.0, 1.7]), np.array([10.0, 5.0, 0.0]), math.radians(60.0)


def street_view() -> View:
    """A camera 1.7 m above the ground looking slightly down a street."""
    cam_to_world = np.linalg.inv(look_along(EYE, TARGET - EYE, [0.0, 0.0, 1.0]))
    return View.perspective(cam_to_world, FOV_Y, 16 / 9, 0.1, 150.0, (1920, 1080))


LIGHT_PARAMETERS = {
    "sun": dict(type="SUN", direction=[0.4, 0.3, -0.6]),
    "point": dict(type="POINT", position=[-40.0, -30.0, 25.0]),
    "spot": dict(type="SPOT", position=[-70.0, -70.0, 40.0], direction=[1.0, 1.0, -0.7], spot_angle=math.radians(70.0)),
}
LIGHTS = {name: Light(**params) for name, params in LIGHT_PARAMETERS.items()}


def new_frame(view: View, light: Light) -> tuple[View, Light]:
    """Copies of the camera and light, as the next frame would describe them."""
    return dataclasses.replace(view, camera_to_world=view.camera_to_world.copy()), dataclasses.replace(light)


def per_call_us(fn, repeat: int, budget_s: float = 0.05) -> tuple[float, float]:
    """(best, median) over ``repeat`` rounds of the mean time per call, in microseconds."""
    fn()
    t0 = time.perf_counter()
    fn()
    once = max(time.perf_counter() - t0, 1e-7)
    loops = max(1, int(budget_s / once))
    rounds = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(loops):
            fn()
        rounds.append((time.perf_counter() - t0) / loops)
    return float(np.min(rounds)) * 1e6, float(np.median(rounds)) * 1e6


def run(n_boxes: int = 10_000, repeat: int = 5) -> dict:
    scene = city_scene(n_boxes)
    view = street_view()
    options = WarpOptions(shadow_map_size=(2048, 2048))
    results: dict = {}
    for lname, light in LIGHTS.items():
        body = intersection_body(view, light, scene)

        def body_only():
            return intersection_body(*new_frame(view, light), scene)

        best, median = per_call_us(body_only, repeat)
        row = {"B": best, "B_median": median,
               "B_vertices": int(len(body.vertices)), "casters": int(body.culled.casters.selected.sum()),
               "receivers": int(body.culled.receivers.selected.sum())}
        for mname in METHODS:
            def frame():
                v, l = new_frame(view, light)
                return compute(mname, v, l, scene, options, body=intersection_body(v, l, scene))
            try:
                frame()
            except Exception as exc:  # a method under construction must not stop the bench
                row[mname] = f"error: {type(exc).__name__}: {exc}"
                continue
            row[mname + "+B"], row[mname + "+B_median"] = per_call_us(frame, repeat)
            row[mname] = row[mname + "+B"] - row["B"]
        results[lname] = row
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.warp_speed", description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = ap.parse_args(argv)
    res = run(args.boxes, args.repeat)
    if args.json:
        json.dump(res, sys.stdout, indent=1)
        print()
        return 0
    print(f"warp core, {args.boxes} boxes, microseconds per call (best of {args.repeat} rounds)")
    names = ["B"] + list(METHODS)
    print(f"{'light':<7}" + "".join(f"{n:>14}" for n in names) + "   B verts  casters receivers")
    for lname, row in res.items():
        cells = []
        for n in names:
            v = row[n]
            cells.append(f"{v:14.0f}" if isinstance(v, float) else f"{'error':>14}")
        print(f"{lname:<7}" + "".join(cells) + f"   {row['B_vertices']:7d} {row['casters']:8d} {row['receivers']:9d}")
    print("B + method (µs):")
    for lname, row in res.items():
        print(f"  {lname:<6}" + "  ".join(f"{m}={row[m + '+B']:.0f}" for m in METHODS if m + "+B" in row))
    for lname, row in res.items():
        for n in METHODS:
            if isinstance(row[n], str):
                print(f"  {lname} {n}: {row[n]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
