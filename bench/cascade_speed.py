"""The cascade's CPU cost per change of view, on the engine's own inputs.

    python -m bench.cascade_speed --save FILE [--scenes forest,city_side_sun,...] [--size 2048]   # needs bpy
    python -m bench.cascade_speed --load FILE [--repeat 7] [--profile] [--json OUT]
    python -m bench.cascade_speed [--repeat 7]                    # both, in one process
    python -m bench.cascade_speed --load FILE --against TREE [--rounds 6] [--repeat 3]   # this tree / TREE, ratios

A frame with the ``cascade`` method spends its CPU time (the engine's "warp" stage) in ``focused_body`` and
``compute("cascade")``: B over what the pre-pass saw, then the splits, each split's B, the warps "auto" tries, the
split search. Both are redone on every change of view (``addon.render.warp_cache`` keeps them only while nothing
changes), so this times them with a new View and Light each call, as a camera drag gives. The inputs are the
engine's: each scene opened as ``bench.rendered_error`` opens it (a sample scene or a box scene), its camera
pre-pass drawn (software OpenGL) and read back as ``fit_warp`` reads it; ``--save`` keeps them in a pickle, so
that two trees can be timed on the same inputs (``--load`` needs no bpy). Each case is timed in rounds that
interleave all cases (a burst of load falls on all alike): the median and best per call, in process CPU time
(``time.process_time``) and wall clock. ``--profile`` prints each case's cProfile, its most costly functions.
``--against`` times another tree (main's: ``git worktree add`` or ``git archive``) on the same inputs: ``--rounds``
rounds, each a fresh process of this tree and one of the other, in turn first, each timing ``--repeat`` calls per
case; per case the median over rounds of each tree's CPU per call, and the ratio (this / other) with the range of
the rounds' ratios (a burst of load on a shared machine shows there, not as a false speed-up).
"""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import io
import json
import os
import pickle
import pstats
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("forest", "chess", "terrain", "floor_wall", "city_side_sun", "city_low_sun", "point_behind_camera",
          "forest_side_sun")
"""The sample scenes and box scenes timed by default: a sun from the side and low, a point light behind the camera
(cube faces)."""


def capture(scenes, size: int) -> dict:
    """Per scene, (view, light, scene bounds, options, the pre-pass's visible region, B's visible region): what
    ``fit_warp`` hands ``compute`` for the cascade at ``size``² with the defaults (``rendered_error``'s settings)."""
    import bpy
    from addon.gpu.context import ensure_gpu_context
    from addon.gpu.pipeline import ShadowFrame
    from addon.gpu.visibility import region_from_frame
    from addon.render.engine import first_look, looks_for_edges, reads_surface
    from addon.scene.describe import describe_scene
    from addon.scene.geometry import GeometryCache
    from addon.warp import focused_body
    from bench.rendered_error import default_settings, open_scene
    cases = {}
    for name in scenes:
        scene = open_scene(name)
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 640, 360, 100
        scene.frame_set(scene.frame_start)
        ensure_gpu_context()
        dg = bpy.context.evaluated_depsgraph_get()
        geometry = GeometryCache().update(dg)
        view, light, bounds = describe_scene(scene, dg, instances=geometry.instances, need_receivers=False)
        options = default_settings("cascade", size).warp
        frame = ShadowFrame(geometry, view, (640, 360))
        frame.camera_prepass()
        edges = looks_for_edges("cascade", options, light)
        visible, _ = region_from_frame(frame, surface=reads_surface("cascade", options) or edges)
        weighed = visible
        if edges:
            weighed = first_look(frame, visible, focused_body(view, light, bounds, options, visible), light, bounds,
                                 options, "cascade")
        bounds = dataclasses.replace(bounds)            # without the culling index (built once per scene)
        cases[name] = (view, light, bounds, options, visible, weighed)
    return cases


def frame_cost(case):
    """One change of view: B and the cascade for a new View and Light (``fit_warp``)."""
    from addon.warp import compute, focused_body
    view, light, bounds, options, visible, weighed = case
    view, light = dataclasses.replace(view, camera_to_world=view.camera_to_world.copy()), dataclasses.replace(light)
    body = focused_body(view, light, bounds, options, visible)
    if weighed is not visible:
        body = dataclasses.replace(body, visible=weighed)
    return compute("cascade", view, light, bounds, options, body=body)


def time_cases(cases: dict, repeat: int) -> dict:
    """{case: {cpu_ms, wall_ms: {median, min, max}}} over ``repeat`` interleaved rounds (one call per case each)."""
    for case in cases.values():
        frame_cost(case)                                  # the culling index, imports
    cpu, wall = {k: [] for k in cases}, {k: [] for k in cases}
    for _ in range(repeat):
        for name, case in cases.items():
            t, c = time.perf_counter(), time.process_time()
            frame_cost(case)
            wall[name].append(1e3 * (time.perf_counter() - t))
            cpu[name].append(1e3 * (time.process_time() - c))

    def stats(v):
        return {"median": statistics.median(v), "min": min(v), "max": max(v)}
    return {k: {"cpu_ms": stats(cpu[k]), "wall_ms": stats(wall[k])} for k in cases}


def profile(case, top: int = 25) -> str:
    """cProfile of three calls, the ``top`` functions by cumulative time."""
    p = cProfile.Profile()
    p.enable()
    for _ in range(3):
        frame_cost(case)
    p.disable()
    out = io.StringIO()
    pstats.Stats(p, stream=out).sort_stats("cumulative").print_stats(top)
    return out.getvalue()


def against(load: Path, tree: Path, scenes: str, rounds: int, repeat: int) -> dict:
    """{case: {cpu_ms: this tree's median, other_ms, ratio, ratio_min, ratio_max}} over ``rounds`` alternating
    rounds of one fresh process per tree (``time_cases`` with ``repeat`` in each: its median per round)."""
    runs = {ROOT: [], tree: []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            for where in ((ROOT, tree) if k % 2 == 0 else (tree, ROOT)):
                out = Path(tmp) / "round.json"
                subprocess.run([sys.executable, "-m", "bench.cascade_speed", "--load", str(load), "--scenes", scenes,
                                "--repeat", str(repeat), "--json", str(out)], cwd=where, check=True,
                               stdout=subprocess.DEVNULL)
                runs[where].append({c: r["cpu_ms"]["median"] for c, r in json.loads(out.read_text()).items()})
    res = {}
    for case in runs[ROOT][0]:
        ours, theirs = ([r[case] for r in runs[w]] for w in (ROOT, tree))
        ratios = [a / b for a, b in zip(ours, theirs)]
        res[case] = {"cpu_ms": statistics.median(ours), "other_ms": statistics.median(theirs),
                     "ratio": statistics.median(ours) / statistics.median(theirs), "ratio_min": min(ratios),
                     "ratio_max": max(ratios)}
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.cascade_speed", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--save", type=Path, help="capture the inputs (bpy) into this pickle and stop")
    ap.add_argument("--load", type=Path, help="time the inputs of this pickle (no bpy)")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--against", type=Path, help="another tree to time alternately with this one (needs --load)")
    ap.add_argument("--rounds", type=int, default=6)
    args = ap.parse_args(argv)
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    if args.against:
        if not args.load:
            ap.error("--against times the inputs of --load")
        res = against(args.load.resolve(), args.against.resolve(), args.scenes, args.rounds, args.repeat)
        print(f"CPU per change of view, ms: median over {args.rounds} alternating rounds ({args.repeat} calls each) "
              f"of this tree and {args.against}; ratio this/other (range over rounds)")
        for k, r in res.items():
            print(f"  {k:22s} {r['cpu_ms']:8.1f} / {r['other_ms']:8.1f}  = {r['ratio']:.3f} "
                  f"({r['ratio_min']:.3f}-{r['ratio_max']:.3f})")
        if args.json:
            args.json.write_text(json.dumps(res, indent=1))
        return 0
    if args.load:
        cases = pickle.loads(args.load.read_bytes())
        cases = {k: v for k, v in cases.items() if k in args.scenes.split(",") or args.scenes == ",".join(SCENES)}
    else:
        cases = capture(args.scenes.split(","), args.size)
        if args.save:
            args.save.write_bytes(pickle.dumps(cases))
            return 0
    res = time_cases(cases, args.repeat)
    print(f"cascade per change of view (focused_body + compute), ms, median (min-max) of {args.repeat} "
          f"interleaved rounds")
    for k, r in res.items():
        c, w = r["cpu_ms"], r["wall_ms"]
        print(f"  {k:22s} cpu {c['median']:8.1f} ({c['min']:.1f}-{c['max']:.1f})   "
              f"wall {w['median']:8.1f} ({w['min']:.1f}-{w['max']:.1f})")
    if args.profile:
        for k, case in cases.items():
            print(f"--- {k}\n{profile(case)}")
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)          # (bpy: Blender 4.2/4.5 may crash or hang at interpreter exit)
