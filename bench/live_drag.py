"""The live viewport's cost per change of view with the cascade: a camera drag through ``live.update``.

    python -m bench.live_drag [--scenes forest,chess,city_side_sun] [--steps 8] [--repeat 3] [--json OUT]   # needs bpy

Each scene is opened as ``bench.rendered_error`` opens it (a sample scene or a box scene) with the default settings
and the ``cascade`` method, and its camera orbits the world's Z axis in steps of ``--degrees``, as a drag moves it.
Every pose is computed twice, interleaved (the order alternating from step to step, so a burst of load falls on both
alike): as the depsgraph handler computed it before (a full ``live.update``: the adaptive split search) and as it does
now (``moving=True``: the PSSM λ splits, ``addon/ui/live.py``); the two poses of a step differ by 1e-6 rad, so each
call sees a changed view. After each pass of the drag the one refinement the resting view gets (``live.refine``'s
update) is timed too. Reported per scene: the median wall-clock ms per change of view of each (the viewport waits
for all of it: describing the view, B, the setup, the overlay geometry and footprint), their ratio, and the
refinement's median.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time

SCENES = ("forest", "chess", "city_side_sun")


def drag_costs(name: str, steps: int, repeat: int, degrees: float) -> dict:
    """Per change of view on scene ``name``: ms lists of the full update ("before"), the moving one ("after") and
    the refinement at rest ("refine")."""
    import bpy
    from mathutils import Matrix

    from addon.ui import live
    from bench.rendered_error import default_settings, open_scene
    scene = open_scene(name)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 640, 360, 100
    scene.frame_set(scene.frame_start)
    settings = default_settings("cascade", 2048)
    camera = scene.camera
    start = camera.matrix_world.copy()
    live.clear()

    def pose(angle):
        camera.matrix_world = Matrix.Rotation(angle, 4, "Z") @ start
        bpy.context.view_layer.update()
        return bpy.context.evaluated_depsgraph_get()

    def timed(**kw):
        t0 = time.perf_counter()
        st = live.update(scene, dg, settings=settings, **kw)
        ms = (time.perf_counter() - t0) * 1000.0
        assert st.ok, st.error
        return ms, st

    dg = pose(0.0)
    live.update(scene, dg, settings=settings)               # the scene bounds, imports, the culling index
    out = {"before": [], "after": [], "refine": []}
    for r in range(repeat):
        for i in range(1, steps + 1):
            modes = ("before", "after") if (i + r) % 2 else ("after", "before")
            for k, mode in enumerate(modes):
                dg = pose(math.radians(degrees * i) + 1e-6 * k)
                ms, st = timed(changed={"view"}, moving=mode == "after")
                assert st.provisional == (mode == "after")
                out[mode].append(ms)
        dg = pose(math.radians(degrees * steps) + 2e-6)      # the view rests: a moving update, then its refinement
        timed(changed={"view"}, moving=True)
        ms, st = timed(changed=())
        assert not st.provisional and st.recomputed == ("setup", "overlays")
        out["refine"].append(ms)
    camera.matrix_world = start
    live.clear()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--steps", type=int, default=8, help="changes of view per pass of the drag")
    ap.add_argument("--repeat", type=int, default=3, help="passes of the drag")
    ap.add_argument("--degrees", type=float, default=0.5, help="orbit per change of view")
    ap.add_argument("--json", help="write the per-call times here")
    args = ap.parse_args(argv)
    rows = {}
    print(f"{'scene':<16} {'before ms':>10} {'after ms':>9} {'ratio':>7} {'refine ms':>10}   (medians of "
          f"{args.steps * args.repeat} changes of view, {args.repeat} refinements)")
    for name in args.scenes.split(","):
        costs = drag_costs(name, args.steps, args.repeat, args.degrees)
        med = {k: statistics.median(v) for k, v in costs.items()}
        rows[name] = {"median_ms": med, "ms": costs}
        print(f"{name:<16} {med['before']:10.1f} {med['after']:9.1f} {med['before'] / med['after']:6.1f}x "
              f"{med['refine']:10.1f}")
        sys.stdout.flush()
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
