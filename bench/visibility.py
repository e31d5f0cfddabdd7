"""What the visible region costs (issue 12: the warp sees what the camera sees).

    python -m bench.visibility [--repeat R] [--gpu] [--json]

Milliseconds per call, best and median over ``repeat`` rounds, interleaved:

* ``region_from_boxes`` - the ray cast without Blender (CLI, viewport, any
  caller of ``addon.warp.compute`` that gives no region) on the street view of
  ``bench.warp_speed``'s city of 100, 2,000 and 10,000 boxes; every call gets
  a new View (the per-scene cache of the last region never hits);
* ``B`` unfocused against ``B`` focused on that region (the k-DOP cut of V);
* ``region_from_boxes`` on the 2,000-box city as a Blender scene gives it
  (``solid=False``: object bounds, every square at a silhouette, so every deep
  box is cut to each square it covers: the live viewport's case), and on 750
  long boxes seen end-on (``cloud_seen_end_on``, also in tests/warp/test_limits.py: the CLI's worst case,
  hundreds of deep boxes per square);
* ``region_from_window_depth`` - the tile reduction of a depth buffer read
  back from the pre-pass, at 640x360, 1280x720 and 1920x1080 (synthetic depth);
* with ``--gpu`` (needs the ``bpy`` module; llvmpipe here): the engine's
  whole visibility step on the 2,000-box city, ``ShadowFrame.camera_prepass``
  then ``addon.gpu.visibility.region_from_frame``, with the tiles reduced on
  the GPU (the default) and with the depth read back and reduced in numpy, at
  the same sizes, against the pre-pass alone.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time

import numpy as np

from addon.warp import intersection_body, region_from_boxes
from addon.warp.types import SceneBounds, View
from addon.warp.visibility import BOX_SAMPLES, BOX_TILE, region_from_window_depth
from bench.warp_speed import LIGHTS, city_boxes, city_scene, street_view

SIZES = ((640, 360), (1280, 720), (1920, 1080))


def cloud_seen_end_on(n: int, seed: int = 1) -> tuple[View, SceneBounds]:
    """``n`` long boxes seen end-on by a camera on their axis: each is deep (near to far) and covers many of the ray
    cast's squares, every square sees hundreds (the (square, box) pairs grow as n times the squares)."""
    rng = np.random.default_rng(seed)
    centre = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(0, 1000, n), rng.uniform(-10, 10, n)])
    half = np.column_stack([rng.uniform(2, 6, n), rng.uniform(50, 400, n), rng.uniform(2, 6, n)])
    looks_along_y = [[1, 0, 0, 0], [0, 0, -1, -30], [0, 1, 0, 0], [0, 0, 0, 1]]
    view = View.perspective(looks_along_y, np.radians(40), 16 / 9, 0.5, 3000, (1280, 720))
    return view, SceneBounds.from_boxes(np.stack([centre - half, centre + half], axis=1))


def timed_ms(fns: dict, repeat: int) -> dict:
    """{name: (best, median)} ms per call, the functions run interleaved round by round."""
    times = {name: [] for name in fns}
    for fn in fns.values():
        fn()                                            # warm: imports, caches, first allocation
    for _ in range(repeat):
        for name, fn in fns.items():
            t = time.perf_counter()
            fn()
            times[name].append((time.perf_counter() - t) * 1e3)
    return {name: (min(v), statistics.median(v)) for name, v in times.items()}


def moved(view):
    """The same camera as a new View (nothing cached on it)."""
    return dataclasses.replace(view, camera_to_world=view.camera_to_world.copy())


def fresh_region(view, scene):
    """``region_from_boxes`` without the scene's cache of its last region."""
    scene.cached(("visible region", BOX_SAMPLES, BOX_TILE), dict).clear()      # region_from_boxes' own key
    return region_from_boxes(moved(view), scene)


def warp_part(repeat: int) -> dict:
    out = {}
    view, light = street_view(), LIGHTS["sun"]
    for n in (100, 2000, 10_000):
        scene = city_scene(n)
        region = region_from_boxes(view, scene)
        fns = {
            f"region_from_boxes, {n} boxes": lambda: fresh_region(view, scene),
            f"B unfocused, {n} boxes": lambda: intersection_body(moved(view), light, scene),
            f"B focused, {n} boxes": lambda: intersection_body(moved(view), light, scene, region),
        }
        out.update(timed_ms(fns, repeat))
    city = city_scene(2000)
    cases = {"2000 boxes as object bounds": (view, dataclasses.replace(city, solid=False)),
             "750 boxes end-on": cloud_seen_end_on(750)}
    out.update(timed_ms({f"region_from_boxes, {name}": lambda v=v, s=s: fresh_region(v, s)
                         for name, (v, s) in cases.items()}, repeat))
    rng = np.random.default_rng(0)
    for w, h in SIZES:
        depth = rng.uniform(0.9, 0.9999, size=(h, w)).astype(np.float32)
        depth[: h // 3] = 1.0                                             # sky
        out.update(timed_ms({f"region_from_window_depth, {w}x{h}":
                             lambda: region_from_window_depth(view, depth)}, repeat))
    return out


def gpu_part(repeat: int) -> dict:
    import bpy  # noqa: F401 - Blender before gpu
    from addon.gpu.context import ensure_gpu_context
    from addon.gpu.pipeline import ShadowFrame
    from addon.gpu.visibility import region_from_frame
    from addon.scene.geometry import SceneGeometry
    ensure_gpu_context()
    boxes = city_boxes(2000)
    corners = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], dtype=np.int32)
    mats = np.zeros((len(boxes), 4, 4))
    mats[:, [0, 1, 2], [0, 1, 2]] = boxes[:, 1] - boxes[:, 0]
    mats[:, :3, 3] = boxes[:, 0]
    mats[:, 3, 3] = 1.0
    geometry = SceneGeometry.from_arrays([("box", corners.astype(np.float32), tris, mats)])
    view = street_view()
    out = {}
    for w, h in SIZES:
        v = dataclasses.replace(view, resolution=(w, h))

        def prepass():
            ShadowFrame(geometry, v, (w, h)).camera_prepass()

        def prepass_and_region(on_gpu):
            frame = ShadowFrame(geometry, v, (w, h))
            frame.camera_prepass()
            region_from_frame(frame, on_gpu=on_gpu)
        out.update(timed_ms({f"pre-pass, {w}x{h}": prepass,
                             f"pre-pass + GPU tiles, {w}x{h}": lambda: prepass_and_region(True),
                             f"pre-pass + read-back + numpy tiles, {w}x{h}": lambda: prepass_and_region(False)},
                            repeat))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.visibility", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--gpu", action="store_true", help="also time the engine's pre-pass read-back (needs bpy)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    results = warp_part(args.repeat)
    if args.gpu:
        results.update(gpu_part(args.repeat))
    if args.json:
        print(json.dumps({k: {"best_ms": b, "median_ms": m} for k, (b, m) in results.items()}, indent=1))
    else:
        for name, (best, median) in results.items():
            print(f"{name:48s} best {best:8.2f} ms   median {median:8.2f} ms")
    return 0


if __name__ == "__main__":
    import os
    import sys
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit
