"""Time per stage of the gpu pipeline on 100k- and 1M-triangle scenes.

    python -m bench.gpu_pipeline [--sizes 1024 2048] [--tris 100000 1000000]
                                 [--camera 1280 720] [--repeat 3] [--method lispsm] [--json]

Scene: a displaced terrain grid (half the triangles) plus a field of boxes in
one mesh (the other half) under a sun, seen obliquely. Stages: extraction
(``GeometryCache.update`` on a fresh cache: positions, corners, triangles),
upload (new batches and instance tables), depth pass, shading (camera
pre-pass + shading pass), read-back. The depth pass is also timed against a
bare draw of the same batches (the casters rendering draws, every face of
each, empty fragment stage) as a ratio, each variant drawing what rendering
draws (:func:`engine_maps`): with the default settings (biasing is applied in
the shading pass; each map culls the faces turned from the light of the
solids it sees from outside, the boxes), with back-face rendering (front
faces culled, no solids) and with linear z (writes ``gl_FragDepth`` where a
map is projective, so no early depth test). Stage times are medians over
``repeat`` runs; the three depth-pass variants run interleaved and report the
best of ``2 * repeat`` (the machine is shared). Every timing ends with a
1-pixel read (no ``gpu.finish`` in the API).
Memory: bytes per map (DEPTH_COMPONENT32F) and per MDSM depth layer
(4 bytes per texel per depth; stored in one RGBA32F texture = 16 B/texel).

Runs Blender as the bpy module headless (Mesa llvmpipe without a GPU).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace

_scratch = tempfile.mkdtemp(prefix="lixel-bench-")
os.environ.setdefault("XDG_CACHE_HOME", os.path.join(_scratch, "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_scratch, "blender-user"))

import numpy as np  # noqa: E402


def build_scene(bpy, n_tris: int, box_meshes: int = 1):
    """Terrain grid + box field with about ``n_tris`` triangles; returns the
    scene. The boxes are one mesh, or ``box_meshes`` (a square number) meshes,
    one per tile of the field: a mesh whose box a map's near plane cuts is
    drawn whole, so one mesh over the field has no faces culled as a solid's
    in any map focused on part of it (``pipeline.seen_from_outside``)."""
    scene = bpy.data.scenes.new(f"bench_{n_tris}")
    half = n_tris // 2
    side = int(math.sqrt(half / 2)) + 1  # side x side quads -> 2 side^2 triangles
    xs = np.linspace(-50, 50, side + 1)
    gx, gy = np.meshgrid(xs, xs)
    gz = 0.4 * np.sin(gx * 0.3) * np.cos(gy * 0.25)
    verts = np.stack([gx, gy, gz], -1).reshape(-1, 3)
    idx = np.arange((side + 1) ** 2).reshape(side + 1, side + 1)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    terrain = _mesh(bpy, "Terrain", verts, quads)
    n_boxes = max((n_tris - 2 * side * side) // 12, 1)
    rng = np.random.default_rng(3)
    centre = np.c_[rng.uniform(-45, 45, (n_boxes, 2)), np.zeros(n_boxes)]
    size = np.c_[rng.uniform(0.2, 1.0, (n_boxes, 2)), rng.uniform(0.5, 4.0, n_boxes)]
    corners = np.array([(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (0.0, 1.0)])
    faces = np.array([(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    across = math.isqrt(box_meshes)
    tile = np.clip(((centre[:, :2] + 45) / 90 * across).astype(int), 0, across - 1) @ [across, 1]
    tiles = [np.flatnonzero(tile == i) for i in range(across * across)]
    boxes = [_mesh(bpy, f"Boxes{i}" if box_meshes > 1 else "Boxes",
                   (corners[None] * size[ids, None, :] + centre[ids, None, :]).reshape(-1, 3),
                   (faces[None] + 8 * np.arange(len(ids))[:, None, None]).reshape(-1, 4))
             for i, ids in enumerate(tiles) if len(ids)]
    for ob in (terrain, *boxes):
        scene.collection.objects.link(ob)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.clip_start, cam.data.clip_end = 0.1, 200.0
    cam.location = (-30, -40, 12)
    from mathutils import Vector
    cam.rotation_euler = (Vector((0, 0, 0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(40), 0, math.radians(30))
    scene.collection.objects.link(sun)
    return scene


def _mesh(bpy, name, verts, quads):
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", np.ascontiguousarray(verts, dtype=np.float32).ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", (np.arange(len(quads)) * 4).astype(np.int32))
    me.update()
    me.validate()
    return bpy.data.objects.new(name, me)


def engine_maps(geometry, view, body, setup, shadow, gpu_scene):
    """A frame whose ``draw_maps`` has drawn ``setup``'s maps as rendering
    does: its ``casters`` (the body's light-extruded hull), and per map
    ``map_casters`` and ``map_solids`` (what ``pipeline.depth_pass`` draws)."""
    from addon.gpu import pipeline
    frame = pipeline.ShadowFrame(geometry, view, scene=gpu_scene, timed=False)
    frame.draw_maps(setup, shadow, body)
    return frame


def run(args) -> list[dict]:
    import bpy

    from addon.gpu import compose, pipeline
    from addon.gpu.batches import GPUScene
    from addon.gpu.context import ensure_gpu_context
    from addon.scene.describe import describe_scene, evaluated_depsgraph
    from addon.scene.geometry import GeometryCache
    from addon.settings import LixelSettings
    from addon.warp import METHODS, WarpOptions, compute, intersection_body

    ensure_gpu_context()
    rows = []
    for n_tris in args.tris:
        scene = build_scene(bpy, n_tris, args.box_meshes)
        scene.render.resolution_x, scene.render.resolution_y = args.camera
        scene.render.resolution_percentage = 100
        dg = evaluated_depsgraph(scene)
        t = time.perf_counter()
        geometry = GeometryCache().update(dg)
        extraction = time.perf_counter() - t
        view, light, bounds = describe_scene(scene, dg, instances=geometry.instances)
        method = args.method if args.method in METHODS else "uniform"
        body = intersection_body(view, light, bounds)
        for size in args.sizes:
            settings = LixelSettings(method=method, warp=WarpOptions(shadow_map_size=(size, size)))
            setup = compute(method, view, light, bounds, settings.warp, body=body)
            gpu_scene = GPUScene()
            first = pipeline.render_shadows(view, light, setup, geometry, settings, body=body, scene=gpu_scene)
            runs = [pipeline.render_shadows(view, light, setup, geometry, settings, body=body, scene=gpu_scene)
                    for _ in range(args.repeat)]
            med = {k: statistics.median(r.timings[k] for r in runs) for k in runs[0].timings}
            linear_setup = compute(method, view, light, bounds, replace(settings.warp, linear_z=True), body=body)
            back = replace(settings.shadow, back_faces=True)
            drawn = {(id(st), sh.back_faces): engine_maps(geometry, view, body, st, sh, gpu_scene)
                     for st, sh in ((setup, settings.shadow), (setup, back), (linear_setup, settings.shadow))}

            def depth(st, shadow, bare=False):
                frame = drawn[id(st), shadow.back_faces]
                casters, solids = (frame.casters, None) if bare else (frame.map_casters, frame.map_solids or None)
                maps = pipeline.depth_pass(st, gpu_scene, casters, shadow, bare=bare, solids=solids)
                compose.sync(maps[-1][1])

            # Interleaved, best of 2*repeat: other processes on the machine slow single runs.
            variants = {"bare": lambda: depth(setup, settings.shadow, bare=True),
                        "default": lambda: depth(setup, settings.shadow),
                        "back": lambda: depth(setup, back),
                        "linear": lambda: depth(linear_setup, settings.shadow)}
            for fn in variants.values():
                fn()  # warm-up (shader compile)
            best = {k: math.inf for k in variants}
            for _ in range(2 * args.repeat):
                for k, fn in variants.items():
                    t = time.perf_counter()
                    fn()
                    best[k] = min(best[k], time.perf_counter() - t)
            rows.append({
                "triangles": geometry.triangle_count,
                "map": size,
                "method": method,
                "camera": list(args.camera),
                "extraction_ms": extraction * 1e3,
                "upload_ms": first.timings["upload"] * 1e3,
                "depth_pass_ms": med["depth_pass"] * 1e3,
                "shading_ms": med["shading"] * 1e3,
                "readback_ms": med["readback"] * 1e3,
                "compose_ms": med["compose"] * 1e3,
                "bare_draw_ms": best["bare"] * 1e3,
                "depth_default_ms": best["default"] * 1e3,
                "depth_back_faces_ms": best["back"] * 1e3,
                "depth_linear_z_ms": best["linear"] * 1e3,
                "ratio_default": best["default"] / best["bare"],
                "ratio_back_faces": best["back"] / best["bare"],
                "ratio_linear_z": best["linear"] / best["bare"],
                "map_bytes": size * size * 4,
                "mdsm_layer_bytes": size * size * 4,
                "mdsm_texture_bytes": size * size * 16,
                "casters_drawn": first.counts.casters_drawn,
            })
        bpy.data.scenes.remove(scene)
    return rows


def print_table(rows) -> None:
    cols = [("triangles", "{:>9}"), ("map", "{:>5}"), ("extraction_ms", "{:>8.1f}"), ("upload_ms", "{:>7.1f}"),
            ("depth_pass_ms", "{:>7.1f}"), ("shading_ms", "{:>8.1f}"), ("readback_ms", "{:>6.1f}"),
            ("bare_draw_ms", "{:>6.1f}"), ("ratio_default", "{:>6.2f}"), ("ratio_back_faces", "{:>6.2f}"),
            ("ratio_linear_z", "{:>6.2f}"),
            ("map_bytes", "{:>10}"), ("mdsm_layer_bytes", "{:>10}")]
    heads = ["tris", "map", "extract", "upload", "depth", "shading", "read", "bare", "r.default", "r.back",
             "r.linear", "map B", "MDSM/layer B"]
    print("  ".join(f"{h:>{max(len(h), len(f.format(rows[0][c])))}}" for h, (c, f) in zip(heads, cols)))
    for r in rows:
        print("  ".join(f"{f.format(r[c]):>{max(len(h), len(f.format(r[c])))}}" for h, (c, f) in zip(heads, cols)))
    print("times in ms (stages: median of runs, including texture allocation and a sync);"
          " bare and r.*: best of interleaved runs, depth pass / bare draw of the same batches"
          " (default settings, back-face rendering, linear z with gl_FragDepth)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024, 2048])
    ap.add_argument("--tris", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--camera", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--method", default="lispsm")
    ap.add_argument("--box-meshes", type=int, default=1, help="the box field as this many meshes (a square number)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from addon.gpu.blas import one_blas_thread
    with one_blas_thread():   # as every frame has it (render_depsgraph)
        rows = run(args)
    if args.json:
        json.dump(rows, sys.stdout, indent=1)
        print()
    else:
        print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
