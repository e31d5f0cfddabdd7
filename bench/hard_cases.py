"""Rendered shadows on numerically hard cases, against exact ray-cast shadows.

    python -m bench.hard_cases                                   # every case, every method, 1024² and 2048²
    python -m bench.hard_cases --cases offset_1e5,contact --methods uniform,lispsm --images out/hard
    python -m bench.hard_cases --list

Each case is a scene of :mod:`bench.rendered_error` (a box scene or a sample scene) edited in Blender: scaled with
its camera's clip range (objects, lights and camera together: the units should not matter), moved 1e5 m from the
origin, given a near plane of 1e-4 m and a far one of 1e4-1e5 m, a sun within 0.1° of the view axis or grazing the
ground, a point light on a surface, inside a box or at the camera, a spot of 179° or 0.5°, an orthographic camera,
1 mm planks 100 m away, a ground of one box ±1e6 to ±1e12 m wide. Each is rendered through the engine's path with
``LixelSettings`` defaults (only the method and map size changed) and classified against the ray-cast truth as
``bench.rendered_error`` does; each case names its well-conditioned twin (``ref``), and the check is that no case
errs much more than its twin where the image shows it: over the pixels facing the light (n·l >= 0.1, the report's
``NDL_MIN``; below it lit and shadowed differ by under a tenth of the light, and at the grazing incidences the hard
cases make, n·l ~ 1e-4, by nothing one can see):

* facing error <= max(RATIO x the twin's, the twin's + SLACK) per method and size (the error over every counted
  pixel is printed beside it);
* no NaN in the shadow, and the render shows what the truth shows (the counted pixels are at least
  COUNTED of the truth's).

The truth is cast relative to the camera (float64 shift, then the float32 BVH), so that a scene far from the
origin is judged as precisely as one at it. Exit status 0 when every check holds.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from bench.checks import report

ROOT = Path(__file__).resolve().parents[1]
SIZES = (1024, 2048)
RATIO, SLACK, SLACK_PIXELS = 1.5, 0.0003, 3
"""A hard case errs 'much more' than its twin above max(RATIO x the twin's error, the twin's + SLACK), SLACK at least
SLACK_PIXELS of the pixels counted (a small spot's few thousand)."""
COUNTED = 0.95
"""The render must show at least this fraction of the pixels the truth counts (else it lost or garbled them)."""


@dataclass(frozen=True)
class Case:
    name: str
    scene: str                                  # a bench.rendered_error scene
    edit: Optional[Callable] = None             # edit(bpy scene), after it is built
    ref: Optional[str] = None                   # the well-conditioned twin
    why: str = ""
    refused: str = ""                           # the refusal (its message starts so) expected instead of a render
    limit: str = ""                             # a measured limit (docs/papers.md, "Hard cases"): why it errs more


# ---------------------------------------------------------------- edits (bpy)

def _root(scene, matrix):
    """Parent every top-level object to an empty with ``matrix``: the whole scene moved, scaled or both."""
    import bpy
    from mathutils import Matrix
    root = bpy.data.objects.new("HardCaseRoot", None)
    scene.collection.objects.link(root)
    for ob in scene.objects:
        if ob.parent is None and ob is not root:
            ob.parent = root
    root.matrix_world = Matrix(matrix)


def scaled(s: float):
    """Objects, lights and the camera's clip range (and ortho scale) scaled by ``s`` about the origin."""
    def edit(scene):
        cam = scene.camera.data
        cam.clip_start, cam.clip_end, cam.ortho_scale = cam.clip_start * s, cam.clip_end * s, cam.ortho_scale * s
        _root(scene, np.diag([s, s, s, 1.0]).tolist())
    return edit


def offset(d):
    """The whole scene moved by ``d`` (m)."""
    def edit(scene):
        m = np.eye(4)
        m[:3, 3] = d
        _root(scene, m.tolist())
    return edit


def clip(near: float, far: float):
    def edit(scene):
        scene.camera.data.clip_start, scene.camera.data.clip_end = near, far
    return edit


def _camera_frame(scene):
    scene.frame_set(scene.frame_start)
    m = np.array(scene.camera.matrix_world)
    return m[:3, 3], -m[:3, 2] / np.linalg.norm(m[:3, 2]), m[:3, 0] / np.linalg.norm(m[:3, 0])


def _set_sun(scene, direction):
    from mathutils import Vector
    sun = next(ob for ob in scene.objects if ob.type == "LIGHT")
    sun.rotation_euler = Vector(direction).normalized().to_track_quat("-Z", "Y").to_euler()


def sun_along_view(sign: float, degrees: float):
    """The sun's light travels along ``sign`` x the view direction, turned ``degrees`` towards the camera's x axis
    (sideways: its height stays the view's)."""
    def edit(scene):
        _, forward, side = _camera_frame(scene)
        a = math.radians(degrees)
        _set_sun(scene, sign * (math.cos(a) * forward + math.sin(a) * side))
    return edit


def sun_elevation(degrees: float):
    """The sun at ``degrees`` above the horizon, keeping its azimuth."""
    def edit(scene):
        sun = next(ob for ob in scene.objects if ob.type == "LIGHT")
        d = -np.array(sun.matrix_world)[:3, 2]
        h = d[:2] / np.linalg.norm(d[:2])
        _set_sun(scene, (*h * math.cos(math.radians(degrees)), -math.sin(math.radians(degrees))))
    return edit


def point_at(where):
    """The scene's light (a point light) moved to ``where``: a position, or 'camera'."""
    def edit(scene):
        light = next(ob for ob in scene.objects if ob.type == "LIGHT")
        light.location = _camera_frame(scene)[0] if where == "camera" else where
    return edit


def spot_cone(degrees: float, location=None, target=None):
    def edit(scene):
        from sample_blends.scenes import _aim
        spot = next(ob for ob in scene.objects if ob.type == "LIGHT")
        spot.data.spot_size = math.radians(degrees)
        if location is not None:
            _aim(spot, location, target)
    return edit


def ortho(scale: float, target=None, distance=None):
    """An orthographic camera of ``ortho_scale`` (m), moved to ``distance`` from ``target`` along its view axis."""
    def edit(scene):
        cam = scene.camera
        cam.data.type, cam.data.ortho_scale = "ORTHO", scale
        if target is not None:
            pos, forward, _ = _camera_frame(scene)
            cam.location = tuple(np.asarray(target) - distance * forward)
            cam.data.clip_start, cam.data.clip_end = 0.01 * distance, 4 * distance
    return edit


def planks(scene):
    """Three 1 mm planks (2 x 1 m) 2 cm, 0.5 m and 1.5 m above the ground, seen 100 m away through a 200 mm lens."""
    import bpy
    from sample_blends.scenes import _aim, box, merge, mesh_object
    for ob in [ob for ob in scene.objects if ob.type == "MESH" and ob.name != "Ground"]:
        bpy.data.objects.remove(ob)
    mesh_object("Planks", *merge([box((x, 0.0, z), (x + 2.0, 1.0, z + 0.001))
                                  for x, z in ((-3.5, 0.02), (-1.0, 0.5), (1.5, 1.5))]))
    cam = scene.camera
    cam.data.lens = 200.0
    _aim(cam, (-60.0, -80.0, 25.0), (0.0, 0.5, 0.5))
    cam.data.clip_start, cam.data.clip_end = 1.0, 300.0


def view_box(scene) -> np.ndarray:
    """(2, 3): the bounding box of the camera's view frustum (its first frame), world space."""
    from mathutils import Vector
    cam = scene.camera
    scene.frame_set(scene.frame_start)
    m = cam.matrix_world
    frame = [Vector(v) for v in cam.data.view_frame(scene=scene)]
    if cam.data.type == "ORTHO":
        pts = [m @ Vector((v.x, v.y, -d)) for v in frame for d in (cam.data.clip_start, cam.data.clip_end)]
    else:
        pts = [m @ (v * (d / -v.z)) for v in frame for d in (cam.data.clip_start, cam.data.clip_end)]
    pts = np.array([tuple(p) for p in pts])
    return np.array([pts.min(axis=0), pts.max(axis=0)])


def ground(half: Optional[float], reach: float = 400.0):
    """The ground or floor (z = 0) as a grid over the view frustum's box grown by ``reach`` m (what can be seen and what can
    shadow it: the trimmed twin), with ``half`` and a ring of quads to ±``half`` m around it: one huge box (an
    endless floor) whose far quads are never seen. (One quad of ±``half`` m cannot be judged here: the truth's
    float32 ray cast shadows such a triangle by itself; docs/papers.md, "Hard cases".)"""
    def edit(scene):
        import bpy
        from sample_blends.scenes import grid, mesh_object
        lo, hi = view_box(scene)[:, :2] + [[-reach], [reach]]
        xs, ys = [lo[0], hi[0]], [lo[1], hi[1]]
        if half is not None:
            xs, ys = [-half, *xs, half], [-half, *ys, half]
        old = scene.objects.get("Ground") or scene.objects["Floor"]
        name = old.name
        bpy.data.objects.remove(old)
        mesh_object(name, *grid(xs, ys), scene.collection)
    return edit


def _then(*edits):
    def edit(scene):
        for e in edits:
            e(scene)
    return edit


DUELING = "dueling frusta: shadow edges along the view, perspective aliasing no single map's warp can lessen"


def cases() -> dict[str, Case]:
    out: list[Case] = []
    for base in ("city_side_sun", "stage_spot", "point_low_in_view", "floor_wall"):
        out.append(Case(base, base, why="the twin at unit scale"))
        for s in (1e-3, 1e3, 1e4):
            out.append(Case(f"{base}_x{s:g}", base, scaled(s), base, f"{base} scaled by {s:g}, clip range too"))
    for base in ("city_side_sun", "floor_wall"):
        out.append(Case(f"{base}_offset_1e5", base, offset((1e5, -1e5, 0.0)), base, f"{base} moved 1e5 m in x and y"))
    out += [
        Case("city_far_1e3", "city_side_sun", clip(0.1, 1e3), None, "the twin: near 0.1 m, far 1e3 m"),
        *(Case(f"city_near_{near:g}_far_1e3", "city_side_sun", clip(near, 1e3), "city_far_1e3",
               f"near {near:g} m, far 1e3 m (1:{1e3 / near:.0e}, within float32 depth)",
               limit="the pre-pass's hyperbolic depth resolves the far tiles coarsely" if near < 1e-3 else "")
          for near in (1e-2, 1e-3, 1e-4)),
        *(Case(f"city_near_1e-4_far_{far:g}", "city_side_sun", clip(1e-4, far), None,
               f"near 1e-4 m, far {far:g} m: beyond float32 depth, refused by name", "Camera 'Camera' clips from")
          for far in (1e4, 1e5)),
        Case("city_sun_10deg_off_view", "city_behind_sun", _then(_down_street, sun_along_view(1.0, 10.0)), None,
             "the camera looks 14° down the street, the sun from behind 10° off its view axis"),
        Case("city_sun_behind_0.05deg", "city_behind_sun", _then(_down_street, sun_along_view(1.0, 0.05)),
             "city_sun_10deg_off_view", "the camera looks 14° down the street, the sun from behind 0.05° off its axis",
             limit=DUELING),
        Case("contact_sun_10deg_off_view", "contact", sun_along_view(1.0, 10.0), None, "the sun 10° off the view axis"),
        Case("contact_sun_behind_0.05deg", "contact", sun_along_view(1.0, 0.05), "contact_sun_10deg_off_view",
             "the sun from behind, 0.05° off the view axis (21° high)"),
        Case("city_sun_front_0.05deg", "city_behind_sun",
             _then(lambda sc: _aim_camera(sc, (0.0, -80.0, 1.8), (0.0, 20.0, 12.0)), sun_along_view(-1.0, 0.05)),
             "city_sun_front_10deg", "the camera looks 7° up, into a sun 0.05° off its view axis (dueling frusta)",
             limit=DUELING),
        Case("city_sun_front_10deg", "city_behind_sun",
             _then(lambda sc: _aim_camera(sc, (0.0, -80.0, 1.8), (0.0, 20.0, 12.0)), sun_along_view(-1.0, 10.0)),
             None, "the camera looks 7° up, into a sun 10° off its view axis"),
        Case("city_sun_grazing_0.5deg", "city_low_sun", sun_elevation(0.5), "city_low_sun", "the sun 0.5° high"),
        Case("city_low_sun", "city_low_sun", why="the twin: the sun 8° high"),
        Case("point_1mm_over_ground", "point_low_in_view", point_at((0.0, -10.0, 0.001)), "point_low_in_view",
             "a point light 1 mm above the ground"),
        Case("point_in_a_box", "point_low_in_view", _then(_add_box((-1.0, -11.0, 0.0), (1.0, -9.0, 3.0)),
                                                            point_at((0.0, -10.0, 1.5))), None,
             "a point light inside a closed 2 x 2 x 3 m box: everything outside it is dark"),
        Case("point_at_camera", "point_low_in_view", point_at("camera"), "point_behind_camera",
             "a point light exactly at the camera"),
        Case("point_behind_camera", "point_behind_camera", why="the twin: a point light behind the camera"),
        Case("stage_spot_179deg", "stage_spot", spot_cone(179.0), "stage_spot", "a spot of 179°"),
        Case("stage_spot_0.5deg", "stage_spot", spot_cone(0.5, (-30.0, -80.0, 100.0), (0.3, 0.3, 0.0)),
             "stage_spot_20deg", "a spot of 0.5° from 130 m away"),
        Case("stage_spot_20deg", "stage_spot", spot_cone(20.0, (-3.0, -8.0, 10.0), (0.3, 0.3, 0.0)), None,
             "the twin: a spot of 20° aimed at the same point"),
        Case("contact_ortho_20m", "contact", ortho(20.0), None, "an orthographic camera 20 m wide"),
        Case("contact_ortho_1cm", "contact", ortho(0.01, (-0.5, -0.4, 0.0), 10.0), None,
             "an orthographic camera 1 cm wide on the edge of a box's shadow"),
        Case("contact_ortho_400m", "contact", ortho(400.0), "contact_ortho_20m",
             "an orthographic camera 400 m wide (the 40 m ground is 64 pixels)"),
        *(Case(f"contact_ortho_{w:g}m", "contact", ortho(w, (-0.5, -0.4, 0.0), 10.0), "contact_ortho_1cm",
               f"an orthographic camera {w:g} m wide 10 m from the ground at a box's shadow edge",
               limit="pixels finer than float32 positions resolve 10 m from the scene's centre") for w in (2e-5, 1e-6)),
        Case("planks_1mm_at_100m", "contact", planks, None, "1 mm planks 100 m away under a 40° sun"),
    ]
    for base in ("city_side_sun", "stage_spot", "point_low_in_view"):
        out.append(Case(f"{base}_ground_trimmed", base, ground(None), None,
                        "the twin: the ground cut to 400 m around the view frustum's box"))
        out += [Case(f"{base}_ground_{half}", base, ground(float(half)), f"{base}_ground_trimmed",
                     f"the ground one box of ±{half} m (its far quads never seen)") for half in ("1e6", "1e9", "1e12")]
    return {c.name: c for c in out}


def _down_street(scene):
    _aim_camera(scene, (0.0, -80.0, 20.0), (0.0, 0.0, 0.0))


def _aim_camera(scene, location, target):
    from sample_blends.scenes import _aim
    _aim(scene.camera, location, target)


def _add_box(lo, hi):
    def edit(scene):
        from sample_blends.scenes import box, mesh_object
        mesh_object("Closed box", *box(lo, hi))
    return edit


# ---------------------------------------------------------------- measuring

def truth_near_camera(view, light, geometry, scene_scale: float):
    """``bench.report.ground_truth.ground_truth`` cast relative to the camera: the triangles, view and light
    shifted by -camera in float64 before the float32 BVH, the points shifted back."""
    from addon.warp.types import View
    from bench.report import ground_truth as G
    o = view.position
    tris = G.world_triangles(geometry)
    tris.tris = tris.tris - o
    c2w = view.camera_to_world.copy()
    c2w[:3, 3] -= o
    near_view = dataclasses.replace(view, camera_to_world=c2w)
    near_light = light if light.position is None else dataclasses.replace(light, position=light.position - o)
    gt = G.ground_truth(near_view, near_light, G.build_bvh(tris), scene_scale)
    gt.points = gt.points + o
    gt.camera = view.position
    return gt


def build(case: Case, resolution):
    """Build ``case`` at ``resolution``, its first frame, with the GPU context ready: (bpy scene, its depsgraph)."""
    import bpy
    from addon.gpu.context import ensure_gpu_context
    from bench.rendered_error import open_scene
    scene = open_scene(case.scene)
    if case.edit is not None:
        case.edit(scene)
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.frame_set(scene.frame_start)
    ensure_gpu_context()
    return scene, bpy.context.evaluated_depsgraph_get()


def case_with_truth(case: Case, resolution):
    """:func:`build` ``case`` and cast its truth: (depsgraph, view, light, truth)."""
    from addon.scene.describe import describe_scene
    from addon.scene.geometry import GeometryCache
    scene, dg = build(case, resolution)
    geometry = GeometryCache().update(dg)
    view, light, bounds = describe_scene(scene, dg)
    corners = view.corners()             # (the scale of what can be seen: a huge ground's would skip every caster)
    return dg, view, light, truth_near_camera(view, light, geometry, bounds.scale([corners.min(0), corners.max(0)]))


@dataclass
class Row:
    case: str
    method: str
    size: int
    error: float
    false_light: float
    false_shadow: float
    facing_error: float     # the error over the counted pixels facing the light (n·l >= 0.1: what the image shows)
    facing: int             # those pixels
    counted: float          # the counted pixels, a fraction of the truth's
    nan: int                # NaN shadow values among the pixels the truth counts
    seconds: float
    failed: str = ""        # the render's error message, if it refused


def measure_case(case: Case, methods, sizes, resolution, images: Optional[Path], log) -> list[Row]:
    from addon.measure import classify
    from addon.render.engine import render_depsgraph
    from addon.warp.types import WarpError
    from bench.rendered_error import _save_error_image, default_settings
    from bench.report.lixel import READ
    from bench.report.analysis import facing
    from bench.report.run import comparable_mask
    t = time.perf_counter()
    try:
        dg, view, light, gt = case_with_truth(case, resolution)
    except WarpError as e:
        log(f"{case.name}: {case.why}; refused: {e}")
        return [Row(case.name, m, size, 1.0, 0.0, 0.0, 1.0, 0, 0.0, 0, 0.0, str(e)) for m in methods for size in sizes]
    valid = max(int(gt.valid.sum()), 1)
    face = facing(gt, light)
    log(f"{case.name}: {case.why}; truth {time.perf_counter() - t:.1f}s, "
        f"{100 * gt.shadow[gt.valid].mean() if gt.valid.any() else 0:.1f}% of {valid} counted pixels in shadow")
    rows = []
    for method in methods:
        for size in sizes:
            t = time.perf_counter()
            try:
                result = render_depsgraph(dg, resolution, settings=default_settings(method, size), read=READ)["result"]
            except WarpError as e:
                rows.append(Row(case.name, method, size, 1.0, 0.0, 0.0, 1.0, 0, 0.0, 0, 0.0, str(e)))
                log(f"  {method:>13} {size:5d}: refused: {e}")
                continue
            seconds = time.perf_counter() - t
            raw = np.asarray(result.shadow_raw, dtype=np.float64)
            shadow = raw >= 0.5
            comparable = comparable_mask(gt, result)
            counts = classify(shadow, gt.shadow, comparable, 2)
            n = max(counts.valid, 1)
            row = Row(case.name, method, size, counts.error_rate, counts.false_light / n, counts.false_shadow / n,
                      *_rate(classify(shadow, gt.shadow, comparable & face, 2)), counts.valid / valid,
                      int(np.isnan(raw[gt.valid]).sum()), seconds)
            rows.append(row)
            log(f"  {method:>13} {size:5d}: {100 * row.error:6.2f}% wrong (light {100 * row.false_light:5.2f}, "
                f"shadow {100 * row.false_shadow:5.2f}), facing {100 * row.facing_error:6.2f}%, {100 * row.counted:5.1f}% counted"
                + (f", {row.nan} NaN" if row.nan else "") + f", {seconds:.2f}s")
            if images is not None:
                _save_error_image(images / f"{case.name}_{method}_{size}.png", shadow, gt.shadow, comparable)
    return rows


def _rate(counts) -> tuple[float, int]:
    return counts.error_rate, counts.valid


def check(rows: list[Row], all_cases: dict[str, Case]) -> list[tuple[bool, str]]:
    by = {(r.case, r.method, r.size): r for r in rows}
    out = []
    for r in rows:
        expected = all_cases[r.case].refused
        if r.failed or expected:
            out.append((bool(expected) and r.failed.startswith(expected),
                        f"{r.case} {r.method} {r.size}: refused: {r.failed or 'no'} (expected: {expected or 'no'})"))
            continue
        out.append((r.nan == 0 and r.counted >= COUNTED,
                    f"{r.case} {r.method} {r.size}: {r.nan} NaN, {100 * r.counted:.1f}% of the truth's pixels counted"))
        twin = by.get((all_cases[r.case].ref, r.method, r.size))
        if twin is not None:
            limit = max(RATIO * twin.facing_error, twin.facing_error + max(SLACK, SLACK_PIXELS / max(r.facing, 1)))
            known = all_cases[r.case].limit
            out.append((r.facing_error <= limit or bool(known), ("" if r.facing_error <= limit or not known else
                        f"known limit ({known}): ") + f"{r.case} {r.method} {r.size}: {100 * r.facing_error:.3f}% wrong "
                        f"facing the light vs its twin {twin.case}'s {100 * twin.facing_error:.3f}% (limit "
                        f"{100 * limit:.3f}%; all counted pixels: {100 * r.error:.3f}% vs {100 * twin.error:.3f}%)"))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.hard_cases", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=None, help="comma-separated case names (default: all; twins are added)")
    ap.add_argument("--methods", default=None, help="comma-separated methods (default: all)")
    ap.add_argument("--sizes", default=",".join(map(str, SIZES)), help="comma-separated map sizes")
    ap.add_argument("--resolution", default="640x360", help="render size WxH")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument("--images", type=Path, default=None, help="write error images (red false shadow, blue false light)")
    ap.add_argument("--list", action="store_true", help="list the cases and stop")
    args = ap.parse_args(argv)
    from bench.rendered_error import _scratch_env
    _scratch_env()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import bpy  # noqa: F401 - Blender before mathutils
    from addon.warp import METHODS
    all_cases = cases()
    if args.list:
        for c in all_cases.values():
            print(f"{c.name:30s} {c.why}" + (f" (twin: {c.ref})" if c.ref else ""))
        return 0
    names = args.cases.split(",") if args.cases else list(all_cases)
    unknown = [n for n in names if n not in all_cases]
    if unknown:
        raise SystemExit(f"unknown case(s) {', '.join(unknown)}: see --list")
    names = list(dict.fromkeys([all_cases[n].ref for n in names if all_cases[n].ref] + names))
    methods = args.methods.split(",") if args.methods else list(METHODS)
    sizes = [int(s) for s in args.sizes.split(",")]
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    rows: list[Row] = []
    for name in names:
        rows += measure_case(all_cases[name], methods, sizes, resolution, args.images, lambda s: print(s, flush=True))
    return report(check(rows, all_cases), args.json, {"rows": [dataclasses.asdict(r) for r in rows]})


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit
