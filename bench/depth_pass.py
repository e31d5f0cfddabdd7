"""What the linear depth costs: the depth pass against a bare draw, and the
shading pass against an earlier revision's.

    python -m bench.depth_pass                       # 1M triangles, 2048², sun and point light
    python -m bench.depth_pass --tris 100000 1000000 --sizes 1024 2048 --repeat 9
    python -m bench.depth_pass --shading-against main~3   # the shading pass, old shaders vs the working tree's
    python -m bench.depth_pass --box-meshes 64            # the boxes as 64 meshes: most are solids a map culls

Scene: ``bench.gpu_pipeline.build_scene`` (a displaced terrain grid and a field
of boxes, half the triangles each; ``--box-meshes``) under its sun, or under a point light 25 m
above the ground off the side (one perspective map or cube faces, as the
method decides). Every variant draws the casters the engine draws (those
``ShadowFrame.draw_maps`` keeps: the body's light-extruded hull) into the
engine's maps. Per light, method and map size it times, interleaved in one
process (the machine is shared, so single runs are noisy):

* ``bare``: every map drawn with its own matrix, every face of every caster,
  an empty fragment stage (``pipeline.depth_pass(bare=True)``), the reference;
* ``depth``: the depth pass as rendering does it with the default settings:
  linear z (the depth row in place of an affine map's z row, or written per
  fragment from one varying for a projective map; ``pipeline.depth_draw``),
  and each map culling the faces turned from the light of the solids it sees
  from outside (``draw_maps``' ``map_solids``: the boxes, not the open terrain);
* ``bare_culled``: ``bare`` with the same faces culled as ``depth`` (the
  cost of linear z alone, at equal work);
* ``whole``: ``depth`` drawing every face (what this benchmark timed before
  the solids' culling, session 5);
* ``hyperbolic``: ``depth`` with the maps' matrices of ``linear_z=False``
  (what rendering did before linear z became the default), its solids culled.

Each repeat runs the variants in turn; the table gives the median over the
repeats of each variant's CPU time (the whole process, every thread; the wall
clock is in the JSON) and the median of the per-repeat ratios depth / bare
(the number the linear-z budget is judged by: the pass rendering runs
against a bare draw of the same batches, at most 1.2), depth / bare_culled
and whole / bare.

``--shading-against REV`` also times the shading pass (1280 x 720, the
engine's Combined and Shadow targets) with REV's gpu_shaders and REV's default
bias (NDC constant + slope scale, hyperbolic maps) against the working tree's,
interleaved, on the same scene. REV must share the working tree's frame
(the deferred shading pass, its uniform block and the pre-pass surface it
reads: one target, the normal packed beside the position, since 06f6584,
in 14 + 15 bits since ecdfa66 (an earlier REV compiles but decodes the
normal wrongly); f213006 and 8a72d06 read the normal from a second target
and no longer compile against this frame). ``--shading-settings same`` gives REV's
shaders the working tree's maps and bias row instead (a revision that already
has the texel-unit biases and linear z: the shaders' own cost alone).

Every timing ends with a 1-pixel read (no ``gpu.finish`` in the API).
Runs Blender as the bpy module headless (Mesa llvmpipe without a GPU).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

_scratch = tempfile.mkdtemp(prefix="lixel-bench-")
os.environ.setdefault("XDG_CACHE_HOME", os.path.join(_scratch, "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_scratch, "blender-user"))


ROOT = Path(__file__).resolve().parents[1]
OLD_BIAS = (0.0005, 1.5, 1.5, 0.02)
READ = frozenset({"combined", "shadow_mask"})
"""What the shading pass writes in the comparison (the engine's Combined and Shadow passes)."""
"""The bias row the shading pass had before the texel-unit biases (constant,
slope factor, PCF reach for k = 3, slope limit; NDC units)."""


def point_light(bpy, scene):
    """Replace the scene's sun with a point light 25 m above the ground off the side."""
    for ob in list(scene.objects):
        if ob.type == "LIGHT":
            bpy.data.objects.remove(ob)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.location = (20.0, -10.0, 25.0)
    scene.collection.objects.link(lamp)


def _time(fn) -> tuple[float, float]:
    """(CPU seconds of the whole process, every thread: Blender's and llvmpipe's
    rasterizer threads; wall seconds) of one call."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.process_time() - cpu, time.perf_counter() - wall


def interleaved(variants: dict, repeat: int) -> dict:
    """{name: [CPU seconds per repeat]} and {name + "_wall": [wall seconds]}:
    the variants run in turn, ``repeat`` times (after one warm-up run each:
    shader compiles, uploads). CPU time is what the ratios use: the machine is
    shared, and other processes stretch the wall clock, not a process's CPU
    time (bench/report/timing.py measured the same)."""
    for fn in variants.values():
        fn()
    times = {k: [] for k in variants}
    times.update({k + "_wall": [] for k in variants})
    for _ in range(repeat):
        for k, fn in variants.items():
            cpu, wall = _time(fn)
            times[k].append(cpu)
            times[k + "_wall"].append(wall)
    return times


def ratio(times: dict, a: str, b: str) -> float:
    """The median over repeats of a's time over b's in the same repeat."""
    return statistics.median(x / y for x, y in zip(times[a], times[b]))


@contextmanager
def shaders_of(rev: str):
    """Lixel's shader module reading ``rev``'s gpu_shaders/ (its caches cleared
    before and after, so shaders built inside come from ``rev``)."""
    from addon.gpu import shaders
    names = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", f"{rev}:gpu_shaders"],
                           check=True, capture_output=True, text=True).stdout.split()
    folder = Path(tempfile.mkdtemp(prefix="lixel-shaders-"))
    for name in names:
        text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:gpu_shaders/{name}"],
                              check=True, capture_output=True, text=True).stdout
        (folder / name).write_text(text)
    caches = (shaders.source, shaders.shade_shader, shaders.prepass_shader, shaders.depth_shader)
    here = shaders.SHADER_DIR
    for c in caches:
        c.cache_clear()
    shaders.SHADER_DIR = folder
    try:
        yield shaders
    finally:
        shaders.SHADER_DIR = here
        for c in caches:
            c.cache_clear()


def run(args) -> list[dict]:
    import bpy

    from addon.gpu import compose, pipeline, shaders
    from addon.gpu.batches import GPUScene
    from addon.gpu.context import ensure_gpu_context
    from addon.scene.describe import describe_scene, evaluated_depsgraph
    from addon.scene.geometry import GeometryCache
    from addon.settings import LixelSettings
    from addon.warp import WarpOptions, compute, intersection_body
    from bench.gpu_pipeline import build_scene, engine_maps

    ensure_gpu_context()
    rows = []
    for n_tris in args.tris:
        for light_kind in args.lights:
            scene = build_scene(bpy, n_tris, args.box_meshes)
            if light_kind == "point":
                point_light(bpy, scene)
            scene.render.resolution_x, scene.render.resolution_y = args.camera
            scene.render.resolution_percentage = 100
            dg = evaluated_depsgraph(scene)
            geometry = GeometryCache().update(dg)
            view, light, bounds = describe_scene(scene, dg, instances=geometry.instances)
            body = intersection_body(view, light, bounds)
            gpu_scene = GPUScene()
            gpu_scene.sync(geometry)
            for method in args.methods:
                for size in args.sizes:
                    settings = LixelSettings(method=method, warp=WarpOptions(shadow_map_size=(size, size)))
                    setup = compute(method, view, light, bounds, settings.warp, body=body)
                    hyperbolic = compute(method, view, light, bounds, replace(settings.warp, linear_z=False), body=body)

                    drawn = {id(st): engine_maps(geometry, view, body, st, settings.shadow, gpu_scene)
                             for st in (setup, hyperbolic)}

                    def depth(st, bare=False, solids=True):
                        frame = drawn[id(st)]
                        casters, culled = (frame.map_casters, frame.map_solids or None) if solids else \
                            (frame.casters, None)
                        maps = pipeline.depth_pass(st, gpu_scene, casters, settings.shadow, bare=bare, solids=culled)
                        compose.sync(maps[-1][1])

                    times = interleaved({"bare": lambda: depth(setup, bare=True, solids=False),
                                         "depth": lambda: depth(setup),
                                         "bare_culled": lambda: depth(setup, bare=True),
                                         "whole": lambda: depth(setup, solids=False),
                                         "hyperbolic": lambda: depth(hyperbolic)}, args.repeat)
                    kinds = ["bare" if m.depth_row is None else
                             ("vertex" if pipeline.is_affine(m.matrix) else "fragment") for m in setup.maps]
                    frame = drawn[id(setup)]
                    row = {"triangles": geometry.triangle_count, "light": light_kind, "method": method, "map": size,
                           "maps": len(setup.maps), "linear_z_in": ",".join(sorted(set(kinds))),
                           "caster_triangles": frame.casters.triangle_count,
                           "solid_triangles": [s.triangle_count for s in frame.map_solids],
                           **{f"{k}_ms": statistics.median(v) * 1e3 for k, v in times.items()},
                           "ratio_depth_bare": ratio(times, "depth", "bare"),
                           "ratio_depth_bare_culled": ratio(times, "depth", "bare_culled"),
                           "ratio_whole_bare": ratio(times, "whole", "bare"),
                           "ratio_hyperbolic_bare": ratio(times, "hyperbolic", "bare"),
                           "ratio_depth_bare_wall": ratio(times, "depth_wall", "bare_wall")}
                    if args.shading_against:
                        row.update(shading(args, pipeline, shaders, compose, geometry, view, light, body, setup,
                                           hyperbolic, settings, gpu_scene))
                    rows.append(row)
                    print(_line(row), flush=True)
            bpy.data.scenes.remove(scene)
    return rows


def shading(args, pipeline, shaders, compose, geometry, view, light, body, setup, hyperbolic, settings, gpu_scene):
    """The shading pass with ``args.shading_against``'s shaders, bias and
    (hyperbolic) maps against the working tree's, interleaved, each on its own
    frame (camera pre-pass and maps drawn once; the engine's passes: the
    combined image and the shadow)."""
    from addon.gpu.targets import TargetPool
    same = args.shading_settings == "same"
    frames = {}
    for name, st in (("old", setup if same else hyperbolic), ("new", setup)):
        frame = pipeline.ShadowFrame(geometry, view, tuple(args.camera), scene=gpu_scene, targets=TargetPool(),
                                     timed=False)
        frame.camera_prepass()
        frame.draw_maps(st, settings.shadow, body)
        frames[name] = (frame, st)
    variant = shaders.ShadeVariant(map_count=len(setup.maps), light=light.type, pcf=settings.shadow.pcf_kernel,
                                   bias=settings.shadow.bias_mode, footprint=False,
                                   linear_z=shaders.agreed(m.depth_row is not None for m in setup.maps),
                                   greater=shaders.agreed(m.depth_test == "GREATER" for m in setup.maps))
    new_shader = shaders.shade_shader(variant)
    with shaders_of(args.shading_against) as old:
        info = old._shade_info(variant)
        if not same:
            info.define("LIXEL_SLOPE_BIAS", "1")  # what the old default bias compiled in
        try:
            old_shader = old._create(info, "old shading pass")
        except shaders.ShaderBuildError as exc:
            raise SystemExit(f"{args.shading_against}'s shading pass does not build against this frame ({exc}): "
                             "it must read the pre-pass surface as this revision writes it (06f6584 or later)") from None
    build, vector = shaders.shade_shader, pipeline.bias_vector

    def shade(name, shader, bias):
        frame, st = frames[name]
        shaders.shade_shader = lambda v: shader
        pipeline.bias_vector = bias
        try:
            frame.shade(light, st, settings.shadow, read=READ)
            compose.sync(frame.targets.framebuffer(colors=(frame._shaded["textures"]["color"],)), color=True)
        finally:
            shaders.shade_shader, pipeline.bias_vector = build, vector

    times = interleaved({"shading_old": lambda: shade("old", old_shader, vector if same else lambda s: OLD_BIAS),
                         "shading_new": lambda: shade("new", new_shader, vector)}, args.repeat)
    return {**{f"{k}_ms": statistics.median(v) * 1e3 for k, v in times.items()},
            "ratio_shading_new_old": ratio(times, "shading_new", "shading_old"),
            "ratio_shading_new_old_wall": ratio(times, "shading_new_wall", "shading_old_wall")}


def _line(r: dict) -> str:
    text = (f"{r['triangles']:>9} tris  {r['light']:>5}  {r['method']:>13}  {r['map']:>5}²  {r['maps']} map(s) "
            f"[{r['linear_z_in']}]  solids {sum(r['solid_triangles']) / max(r['caster_triangles'] * r['maps'], 1):.0%}"
            f"  CPU: bare {r['bare_ms']:7.1f} ms  depth {r['depth_ms']:7.1f} ms  "
            f"bare culled {r['bare_culled_ms']:7.1f} ms  whole {r['whole_ms']:7.1f} ms  "
            f"hyperbolic {r['hyperbolic_ms']:7.1f} ms  depth/bare {r['ratio_depth_bare']:.3f}  "
            f"depth/bare culled {r['ratio_depth_bare_culled']:.3f}  whole/bare {r['ratio_whole_bare']:.3f}  "
            f"hyperbolic/bare {r['ratio_hyperbolic_bare']:.3f} (wall {r['ratio_depth_bare_wall']:.3f})")
    if "ratio_shading_new_old" in r:
        text += (f"  shading old {r['shading_old_ms']:7.1f} ms  new {r['shading_new_ms']:7.1f} ms  "
                 f"new/old {r['ratio_shading_new_old']:.3f} (wall {r['ratio_shading_new_old_wall']:.3f})")
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.depth_pass", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tris", type=int, nargs="+", default=[1_000_000])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2048])
    ap.add_argument("--lights", nargs="+", default=["sun", "point"], choices=["sun", "point"])
    ap.add_argument("--methods", nargs="+", default=["uniform", "lispsm", "psm", "plane_optimal"])
    ap.add_argument("--camera", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--box-meshes", type=int, default=1,
                    help="the box field as this many meshes (a square number), one per tile: 1 (the default) "
                         "is one mesh that every map's near plane cuts, so no map culls faces of it")
    ap.add_argument("--shading-against", default=None, metavar="REV",
                    help="also time the shading pass with this git revision's shaders against the working tree's")
    ap.add_argument("--shading-settings", choices=["before-biases", "same"], default="before-biases",
                    help="REV's shaders with the bias row and hyperbolic maps of before the texel-unit biases "
                         "(f213006's), or with the working tree's maps and bias row")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = ap.parse_args(argv)
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import bpy  # noqa: F401 - Blender before mathutils
    from addon.gpu.blas import one_blas_thread
    with one_blas_thread():   # as every frame has it (render_depsgraph): the bare draw and the passes alike
        rows = run(args)
    worst = max(r["ratio_depth_bare"] for r in rows)
    line = (f"\nworst depth pass / bare draw: {worst:.3f} (budget 1.2); against a bare draw culling the same "
            f"faces: {max(r['ratio_depth_bare_culled'] for r in rows):.3f}")
    if args.shading_against:
        line += "; shading new / old: " + ", ".join(f"{r['ratio_shading_new_old']:.3f}" for r in rows)
    print(line)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit
