"""A Lixel frame against the rasteriser's floor and against Blender's own engines.

    python -m bench.frame [--scenes forest chess tris1m ...] [--resolution 1280 720]
                          [--size 2048] [--method lispsm] [--repeat 7] [--peers workbench cycles]
                          [--json FILE]

For each scene, in one process, every measurement below runs once per round,
in turn, for ``--repeat`` rounds (interleaved, so the load of a shared machine
falls on all of them alike); each is reported as the median with its min and
max, in wall-clock time and in CPU time (``time.process_time``: the whole
process, every thread, so Mesa llvmpipe's rasterizer threads and Cycles'
render threads count; other processes on a shared machine stretch the wall
clock but not this). Ratios are given in both:

* **warm frame**: ``bpy.ops.render.render`` with the LIXEL engine on an
  unchanged scene (F12 as the user runs it: Blender's render depsgraph, the
  frame, the four passes written into the render result);
* **cold frame**: the same after dropping every Lixel cache (scene geometry,
  batches, instance matrices, draw lists, render targets, B and the warp;
  compiled shaders are kept);
* **stages**: ``render_depsgraph`` with a wait for the GPU after every stage,
  so each stage's time is its own (the F12 frame waits once, at the read-back);
* **stages in CPU time**: the same with the library's stage clock reading
  the process's CPU time (:func:`cpu_clock`); each stage waits for the GPU,
  so a GPU stage's CPU time is its own rasterisation (llvmpipe's threads);
* **CPU time outside GPU waits**: the stages that never touch the GPU
  (extraction, describe, warp, cull, upload when nothing changed) plus
  writing the render passes, in CPU time (and the same stages' wall clock);
* **the floor**: a bare depth draw of the frame's casters into its maps (same
  matrices and sizes, empty fragment stage), a bare depth draw of the frame's
  receivers from the camera at the output resolution, and a trivial
  full-screen pass writing an RGBA32F target at the output resolution, each
  ending with a wait for the GPU;
* **peers**: Workbench (the scene's own anti-aliasing setting, and with it
  off) and Cycles at 1 sample, F12 of the same view at the same resolution;
* **Blender's own F12**: an engine that draws nothing and writes an empty
  Combined pass (the part of every engine's F12 that is Blender's).

Scenes: ``forest`` and ``chess`` (sample_blends), ``forest_wide`` (the
forest's 10,000 geometry-node trees seen whole from above its edge: every
tree is drawn), ``instances_100k`` (the forest with 100,000 trees),
``tris1m`` (bench.gpu_pipeline's 1M-triangle terrain and boxes).

The machine is shared and has 2 cores, so absolute times drift; ratios taken
within one run are what to compare.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from contextlib import contextmanager

_scratch = tempfile.mkdtemp(prefix="lixel-bench-frame-")
os.environ.setdefault("XDG_CACHE_HOME", os.path.join(_scratch, "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_scratch, "blender-user"))

import numpy as np  # noqa: E402

SCENES = ("forest", "chess", "tris1m", "forest_wide", "instances_100k")
CPU_STAGES = ("extraction", "describe", "warp", "cull", "upload", "passes")
"""Stages that never touch the GPU on a warm frame (upload: nothing changed, nothing is uploaded)."""


# --------------------------------------------------------------------------- scenes

def _open_sample(bpy, name: str):
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "sample_blends" / f"{name}.blend"
    bpy.ops.wm.open_mainfile(filepath=str(path))
    return bpy.context.scene


def _set_tree_count(bpy, scene, count: int) -> None:
    for tree in bpy.data.node_groups:
        for node in tree.nodes:
            if node.bl_idname == "GeometryNodePoints":
                node.inputs["Count"].default_value = int(count)


def _same_in_viewport(scene) -> None:
    """Objects hidden from renders hidden from the viewport too, so the viewport
    depsgraph (the stage runs) draws what F12's render depsgraph draws."""
    for ob in scene.objects:
        if ob.hide_render:
            ob.hide_viewport = True


def make_scene(bpy, name: str):
    """The scene called ``name`` (see the module docstring), made the window's scene."""
    scene = _make_scene(bpy, name)
    _same_in_viewport(scene)
    return scene


def _make_scene(bpy, name: str):
    if name in ("forest", "chess"):
        return _open_sample(bpy, name)
    if name == "forest_wide":
        scene = _open_sample(bpy, "forest")
        cam = scene.camera
        cam.animation_data_clear()
        cam.data.clip_end = 600.0
        cam.location = (-190.0, -190.0, 90.0)
        from mathutils import Vector
        cam.rotation_euler = (Vector((10.0, 10.0, 0.0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
        return scene
    if name == "instances_100k":
        scene = _open_sample(bpy, "forest")
        _set_tree_count(bpy, scene, 100_000)
        return scene
    if name == "tris1m":
        from bench.gpu_pipeline import build_scene
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = build_scene(bpy, 1_000_000)
        bpy.context.window.scene = scene if bpy.context.window else None
        return scene
    raise ValueError(f"unknown scene {name!r}; choose from {', '.join(SCENES)}")


# --------------------------------------------------------------------------- measuring

class _CPUClock:
    """The ``time`` module with ``perf_counter`` reading the process's CPU time."""

    perf_counter = staticmethod(time.process_time)

    def __getattr__(self, name):
        return getattr(time, name)


@contextmanager
def cpu_clock():
    """Lixel's stage timings (``RenderResult.timings``) in CPU time of the
    process (every thread: llvmpipe's rasterizer threads too): waits for the
    GPU and other processes' time slices are left out."""
    from addon.gpu import pipeline, visibility
    from addon.render import engine
    modules = (engine, pipeline, visibility)
    saved = [m.time for m in modules]
    for m in modules:
        m.time = _CPUClock()
    try:
        yield
    finally:
        for m, t in zip(modules, saved):
            m.time = t


def stats(values) -> dict:
    v = [float(x) * 1e3 for x in values]
    return {"median": statistics.median(v), "min": min(v), "max": max(v), "n": len(v)}


def _trivial_fullscreen_shader():
    import gpu
    from addon.gpu import shaders
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC3", "pos")
    info.fragment_out(0, "VEC4", "out_color")
    info.vertex_source(shaders.source("fullscreen_vert.glsl"))
    info.fragment_source("void main()\n{\n  out_color = vec4(gl_FragCoord.xy * 1e-3, 0.0, 1.0);\n}\n")
    return gpu.shader.create_from_info(info)


class Floor:
    """The rasteriser's floor for one frame: bare depth of its casters into its
    maps, bare depth of its receivers from the camera, a trivial full-screen pass."""

    def __init__(self, frame, setup):
        from addon.gpu.targets import TargetPool
        from addon.settings import ShadowSettings
        self.frame, self.setup = frame, setup
        self.targets = TargetPool()
        self.shadow = ShadowSettings()
        self.fullscreen = _trivial_fullscreen_shader()

    def depth(self) -> None:
        from addon.gpu import compose, pipeline
        maps = pipeline.depth_pass(self.setup, self.frame.scene, self.frame.casters, self.shadow, self.targets,
                                   bare=True)
        compose.sync(maps[-1][1])

    def camera(self) -> None:
        import gpu
        from addon.gpu import compose, shaders
        f = self.frame
        depth = self.targets.texture("camera", f.size, "DEPTH_COMPONENT32F")
        fb = self.targets.framebuffer(depth=depth)
        with fb.bind():
            gpu.state.viewport_set(0, 0, *f.size)
            fb.clear(depth=1.0)
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            sh = shaders.camera_depth_shader()
            sh.bind()
            sh.uniform_float("u_view_proj", f._view_proj)
            f.scene.draw(sh, f.solids)          # every receiver the frame draws, no face culled
            f.scene.draw(sh, f.receivers)
            gpu.state.depth_mask_set(False)
            gpu.state.depth_test_set("NONE")
        compose.sync(fb)

    def full_screen(self) -> None:
        import gpu
        from addon.gpu import compose
        f = self.frame
        tex = self.targets.texture("colour", f.size, "RGBA32F")
        fb = self.targets.framebuffer(colors=(tex,))
        with fb.bind():
            gpu.state.viewport_set(0, 0, *f.size)
            self.fullscreen.bind()
            compose.fullscreen_batch().draw(self.fullscreen)
        compose.sync(fb, color=True)


def _lixel_frame(dg, settings):
    """A frame as render_depsgraph makes it, kept open (the floor draws its lists):
    the same B (fitted to what the pre-pass saw, as the engine's), hence the
    same maps' matrices and the same casters."""
    from addon.gpu.pipeline import ShadowFrame
    from addon.render.engine import fit_warp
    from addon.scene.owned import is_debug_object
    from addon.scene.describe import describe_scene
    from addon.scene.geometry import shared_cache
    scene = dg.scene.original if dg.scene.is_evaluated else dg.scene
    geometry = shared_cache().update(dg, exclude=is_debug_object)
    view, light, bounds = describe_scene(scene, dg, instances=geometry.instances)
    frame = ShadowFrame(geometry, view, view.resolution)
    frame.camera_prepass()
    body, setup, _ = fit_warp(frame, light, bounds, settings.warp, settings.method)
    frame.draw_maps(setup, settings.shadow, body)
    return frame, setup


def drop_caches() -> None:
    """Forget every Lixel cache (a cold frame); compiled shaders stay."""
    from addon.gpu import batches, targets
    from addon.render import warp_cache
    from addon.scene import geometry
    geometry.shared_cache().clear()
    warp_cache.shared_warps().clear()
    batches.shared_batches().clear()
    batches._shared_scene = None
    targets.shared_targets().clear()


_NULL_ENGINE = None


def null_engine():
    """A render engine that draws nothing and writes an empty Combined pass: what
    F12 costs in Blender itself (render depsgraph, result, the pass's pages)."""
    global _NULL_ENGINE
    if _NULL_ENGINE is None:
        import bpy

        class LixelBenchNullEngine(bpy.types.RenderEngine):
            bl_idname = "LIXEL_BENCH_NULL"
            bl_label = "Lixel bench: nothing"
            bl_use_gpu_context = True

            def render(self, depsgraph):
                w, h = (int(v) for v in _resolution(depsgraph.scene))
                result = self.begin_result(0, 0, w, h)
                result.layers[0].passes["Combined"].rect.foreach_set(np.zeros(w * h * 4, np.float32))
                self.end_result(result)

        _NULL_ENGINE = LixelBenchNullEngine
    return _NULL_ENGINE


def _resolution(scene):
    r = scene.render
    return r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100


def measure(name: str, args) -> dict:
    import bpy
    from addon.render import engine
    from addon.render.engine import render_depsgraph
    from addon.settings import LixelSettings
    from addon.warp import WarpOptions

    t = time.perf_counter()
    scene = make_scene(bpy, name)
    scene.render.resolution_x, scene.render.resolution_y = args.resolution
    scene.render.resolution_percentage = 100
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.engine = "LIXEL"
    settings = LixelSettings(method=args.method, warp=WarpOptions(shadow_map_size=(args.size, args.size)))
    engine.scene_settings = lambda _scene, _s=settings: _s          # F12 renders with these settings
    dg = bpy.context.evaluated_depsgraph_get()
    build_s = time.perf_counter() - t

    def f12(engine_id: str, aa: str | None = None):
        def run():
            old_aa = scene.display.render_aa
            scene.render.engine = engine_id
            if aa is not None:
                scene.display.render_aa = aa
            try:
                bpy.ops.render.render(scene=scene.name)
            finally:
                scene.render.engine = "LIXEL"
                scene.display.render_aa = old_aa
        return run

    results: dict = {}

    def lixel_warm():
        with engine.watch_renders() as got, cpu_clock():   # only the library's stage timings read CPU time
            bpy.ops.render.render(scene=scene.name)
        results["last_f12"] = got[-1]["result"]

    def lixel_cold():
        drop_caches()
        bpy.ops.render.render(scene=scene.name)

    def stages():
        out = render_depsgraph(dg, settings=settings, timed=True)
        results.setdefault("stages", []).append(out["result"].timings)
        results["counts"] = out["result"].counts

    def stages_cpu():
        with cpu_clock():
            out = render_depsgraph(dg, settings=settings, timed=True)
        results.setdefault("stages_cpu", []).append(out["result"].timings)

    def internal():
        render_depsgraph(dg, settings=settings, timed=False)

    lixel_warm()                      # compile, upload, allocate
    stages()
    frame, setup = _lixel_frame(dg, settings)
    drawn = render_depsgraph(dg, settings=settings)["setup"]
    if len(setup.maps) != len(drawn.maps) or not all(
            np.array_equal(a.matrix, b.matrix) and a.size == b.size for a, b in zip(setup.maps, drawn.maps)):
        raise RuntimeError(f"{name}: the floor's maps are not the frame's")
    floor = Floor(frame, setup)
    runs = {"warm": lixel_warm, "internal": internal, "cold": lixel_cold, "stages": stages, "stages_cpu": stages_cpu,
            "floor_depth": floor.depth, "floor_camera": floor.camera, "floor_full_screen": floor.full_screen}
    runs["blender_f12"] = f12(null_engine().bl_idname)
    if "workbench" in args.peers:
        runs["workbench"] = f12("BLENDER_WORKBENCH")
        runs["workbench_aa_off"] = f12("BLENDER_WORKBENCH", "OFF")
    if "cycles" in args.peers:
        runs["cycles_1spp"] = f12("CYCLES")
    for fn in runs.values():
        fn()                          # warm-up (shader compilation, Blender's own caches)
    results.pop("stages", None)
    results.pop("stages_cpu", None)
    times: dict = {k: [] for k in runs}
    cpu_times: dict = {k: [] for k in runs}
    passes: list = []
    for _ in range(args.repeat):
        for key, fn in runs.items():
            if key == "cycles_1spp" and len(times[key]) >= args.cycles_repeat:
                continue
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times[key].append(time.perf_counter() - t0)
            cpu_times[key].append(time.process_time() - c0)
            if key == "warm":
                passes.append(results["last_f12"].timings.get("passes", 0.0))
            if key == "cold":                 # warm again what the cold frame dropped (both depsgraphs), untimed
                bpy.ops.render.render(scene=scene.name)
                internal()
    stage_runs = results["stages"]
    stage_names = list(stage_runs[0])
    stage_stats = {s: stats([r.get(s, 0.0) for r in stage_runs]) for s in stage_names}
    stage_stats["passes"] = stats(passes)
    cpu_runs = results["stages_cpu"]
    stage_cpu_stats = {s: stats([r.get(s, 0.0) for r in cpu_runs]) for s in stage_names}
    stage_cpu_stats["passes"] = stats(passes)
    cpu = [sum(r.get(s, 0.0) for s in CPU_STAGES if s != "passes") + p for r, p in zip(cpu_runs, passes)]
    floor_runs = [a + b + c for a, b, c in zip(times["floor_depth"], times["floor_camera"],
                                              times["floor_full_screen"])]
    floor_cpu = [a + b + c for a, b, c in zip(cpu_times["floor_depth"], cpu_times["floor_camera"],
                                             cpu_times["floor_full_screen"])]
    row = {
        "scene": name, "resolution": list(args.resolution), "map": args.size, "method": args.method,
        "build_s": build_s,
        "counts": vars(results["counts"]),
        "warm": stats(times["warm"]), "internal": stats(times["internal"]), "cold": stats(times["cold"]),
        "floor": stats(floor_runs),
        "floor_parts": {k[6:]: stats(times[k]) for k in ("floor_depth", "floor_camera", "floor_full_screen")},
        "cpu": {k: stats(v) for k, v in cpu_times.items()},
        "floor_cpu": stats(floor_cpu),
        "floor_parts_cpu": {k[6:]: stats(cpu_times[k]) for k in ("floor_depth", "floor_camera", "floor_full_screen")},
        "stages": stage_stats,
        "stages_cpu": stage_cpu_stats,
        "cpu_outside_gpu": stats(cpu),
        "cpu_outside_gpu_wall": stats([sum(r.get(s, 0.0) for s in CPU_STAGES if s != "passes") for r in stage_runs]),
    }
    row["ratio_warm_to_floor"] = row["warm"]["median"] / row["floor"]["median"]
    row["ratio_internal_to_floor"] = row["internal"]["median"] / row["floor"]["median"]
    row["cpu_ratio_warm_to_floor"] = row["cpu"]["warm"]["median"] / row["floor_cpu"]["median"]
    row["cpu_ratio_internal_to_floor"] = row["cpu"]["internal"]["median"] / row["floor_cpu"]["median"]
    row["blender_f12"] = stats(times["blender_f12"])
    for peer in ("workbench", "workbench_aa_off", "cycles_1spp"):
        if peer in times:
            row[peer] = stats(times[peer])
            row[f"ratio_warm_to_{peer}"] = row["warm"]["median"] / row[peer]["median"]
            row[f"cpu_ratio_warm_to_{peer}"] = row["cpu"]["warm"]["median"] / row["cpu"][peer]["median"]
    row["workbench_aa"] = scene.display.render_aa
    return row


# --------------------------------------------------------------------------- output

def _ms(s: dict) -> str:
    return f"{s['median']:.1f} ({s['min']:.1f}-{s['max']:.1f})"


def print_row(r: dict) -> None:
    c = r["counts"]
    print(f"\n== {r['scene']}: {r['resolution'][0]}x{r['resolution'][1]}, {r['map']}² {r['method']}; "
          f"{c['instances']:,} instances, casters drawn {c['casters_drawn']:,} ({c['caster_triangles_drawn']:,} tris), "
          f"receivers drawn {c['receivers_drawn']:,} ({c['receiver_triangles_drawn']:,} tris)")
    cpu = r["cpu"]
    print("  wall ms: median (min-max); CPU ms: median")
    print(f"  warm frame (F12)      {_ms(r['warm'])}   CPU {cpu['warm']['median']:.1f}")
    print(f"  frame inside F12      {_ms(r['internal'])}   CPU {cpu['internal']['median']:.1f}"
          "   (render_depsgraph, one wait)")
    print(f"  cold frame (F12)      {_ms(r['cold'])}   CPU {cpu['cold']['median']:.1f}")
    print(f"  floor                 {_ms(r['floor'])}   CPU {r['floor_cpu']['median']:.1f}   = " + " + ".join(
        f"{k} {_ms(v)} (CPU {r['floor_parts_cpu'][k]['median']:.1f})" for k, v in r["floor_parts"].items()))
    print(f"  warm / floor          {r['ratio_warm_to_floor']:.2f}   (inside F12: {r['ratio_internal_to_floor']:.2f}); "
          f"CPU {r['cpu_ratio_warm_to_floor']:.2f} (inside F12: {r['cpu_ratio_internal_to_floor']:.2f})")
    print(f"  Blender's own F12     {_ms(r['blender_f12'])}   CPU {cpu['blender_f12']['median']:.1f}"
          "   (an engine that writes an empty Combined pass)")
    print(f"  CPU outside GPU waits {_ms(r['cpu_outside_gpu'])}   (CPU: "
          + ", ".join(CPU_STAGES) + "; the same stages' wall clock without passes: "
          f"{_ms(r['cpu_outside_gpu_wall'])})")
    print("  stages, wall (each waits for the GPU): " + ", ".join(f"{k} {_ms(v)}" for k, v in r["stages"].items()))
    print("  stages, CPU: " + ", ".join(f"{k} {v['median']:.1f}" for k, v in r["stages_cpu"].items()))
    for peer, label in (("workbench", f"Workbench (AA {r['workbench_aa']})"), ("workbench_aa_off", "Workbench (AA off)"),
                        ("cycles_1spp", "Cycles 1 spp")):
        if peer in r:
            print(f"  {label:<21} {_ms(r[peer])}   CPU {cpu[peer]['median']:.1f}   Lixel warm / this: "
                  f"{r[f'ratio_warm_to_{peer}']:.2f} (CPU {r[f'cpu_ratio_warm_to_{peer}']:.2f})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["forest", "chess", "tris1m"], choices=SCENES)
    ap.add_argument("--resolution", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--method", default="lispsm")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--cycles-repeat", type=int, default=3, help="rounds that also render Cycles (it is slow)")
    ap.add_argument("--peers", nargs="*", default=["workbench", "cycles"], choices=["workbench", "cycles"])
    ap.add_argument("--json", help="also write the numbers here")
    args = ap.parse_args(argv)
    import bpy
    from addon.gpu.blas import one_blas_thread
    from addon.gpu.context import ensure_gpu_context
    from addon.render import engine
    engine.register()
    bpy.utils.register_class(null_engine())
    rows = []
    try:
        ensure_gpu_context()
        with one_blas_thread():   # as every frame has it (render_depsgraph): the floor and the rest too
            for name in args.scenes:
                row = measure(name, args)
                rows.append(row)
                print_row(row)
                sys.stdout.flush()
    finally:
        bpy.utils.unregister_class(null_engine())
        engine.unregister()
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
