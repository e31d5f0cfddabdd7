"""How far the first look's shadow-edge directions lie from the true shadow edges', and what the first look costs.

    python -m bench.edge_directions --scenes gen43_05_point_low_in_view,gen86_02_low_sun
    python -m bench.edge_directions --generated 12 --seeds 1,2,3,41 --repeat 5

Each scene is opened like ``bench.rendered_error`` (``scene_with_truth``: the ray-cast truth at the render size),
and the engine takes its first look as ``fit_warp`` does for the cascade (``addon.gpu.visibility.shadow_edges`` on the
camera pre-pass's surface samples, the body focused on them). Each edge sample (a surface sample the first look gives
a direction d) is set against the true shadow edge nearest it on screen: the nearest pixel, within ``--radius``
pixels, of the truth's straight edges (``bench.edge_footprint``: no corner within a pixel) on a surface turned as the
sample's (normals within :data:`SAME_PLANE`); its normal on screen n_s, from ``shadow_edge_normals`` at its default
radius (the disc's gradient: 1.2° median error on straight edges), is carried onto the sample's plane as the first
look carries its own gradient: the true edge runs along n × D_viewᵀ n_s (D_view·d ⟂ n_s, n·d = 0). Two angles
between the lines (0..90°): on the surface, and in the first look's map's texels (D_M·d against D_M·d_true), the
space where the cascade's pick and PSM's edge turn read an edge's angle to the texel axes
(``partition.receivers.filter_losses``). Printed per scene and over all: the samples matched, and the angles'
median, p90 and the share within 2° and 5°; over all also for the samples away from the true shadow's corners
(:data:`CORNER_PIXELS`), where a window of texels sees two edges and no one direction is right.

``--repeat N`` also times the first look: the median wall time of N calls of ``shadow_edges`` (the coarse map drawn
and read back, then ``at_shadow_edge``) and of ``at_shadow_edge`` alone on the same map, per scene, in ms.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SAME_PLANE = 0.98
"""A true edge pixel stands for an edge sample only on a surface whose normal is within acos(0.98) ≈ 11° of its."""
CORNER_PIXELS = 12
"""Samples this many pixels or fewer from a corner of the true shadow (``bench.edge_footprint.corners``) are also
left out of a second summary: the straight edges alone, where one direction is the edge's."""


def first_look(dg, geometry, view, light, bounds, size: int = 2048):
    """The cascade's first look as ``fit_warp`` takes it: (frame, region, body, options, the region with the edges)."""
    from addon.gpu.pipeline import ShadowFrame
    from addon.gpu.visibility import region_from_frame, shadow_edges
    from addon.warp import focused_body
    from bench.rendered_error import default_settings
    options = default_settings("cascade", size).warp
    frame = ShadowFrame(geometry, view, read=set())
    frame.camera_prepass()
    region, _ = region_from_frame(frame, surface=True)
    body = focused_body(view, light, bounds, options, region)
    return frame, region, body, options, shadow_edges(frame, region, body, light, bounds, options)


def true_edges(gt):
    """(the truth's straight edge pixels (H, W), their unit normals on screen (H, W, 2), x right and y up, and the
    pixels within :data:`CORNER_PIXELS` of a corner)."""
    from addon.measure.errors import dilate, shadow_edges
    from addon.measure.footprint import shadow_edge_normals
    from bench.edge_footprint import corners
    turning = shadow_edge_normals(gt.shadow, gt.valid, 1)
    normals = shadow_edge_normals(gt.shadow, gt.valid)
    edges = shadow_edges(gt.shadow, gt.valid) & np.isfinite(turning[..., 0]) & np.isfinite(normals[..., 0])
    corner = corners(edges, turning)
    return edges & ~dilate(corner, 1), normals, dilate(corner, CORNER_PIXELS)


def nearest_true(view, gt, straight, points, normals, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of (K, 3) sample ``points`` (unit ``normals``): the (row, col) of the nearest ``straight`` pixel within
    ``radius`` pixels on a surface turned as the sample's, and whether there is one."""
    from addon.warp.geometry import raster_position
    h, w = straight.shape
    at = np.floor(raster_position(view.world_to_clip, view.resolution, points)).astype(np.int64)    # (col, row)
    dy, dx = np.mgrid[-radius:radius + 1, -radius:radius + 1].reshape(2, -1)
    rows, cols = at[:, 1:2] + dy, at[:, 0:1] + dx                                                   # (K, (2r+1)²)
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    r, c = np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)
    ok = inside & straight[r, c] & (np.abs(np.einsum("kqj,kj->kq", gt.normals[r, c], normals)) >= SAME_PLANE)
    distance = np.where(ok, dx * dx + dy * dy, np.inf)
    best = np.argmin(distance, axis=1)
    k = np.arange(len(points))
    return np.stack([r[k, best], c[k, best]], 1), np.isfinite(distance[k, best])


def line_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees (0..90) between the lines along the rows of ``a`` and ``b``."""
    cos = np.abs(np.einsum("ij,ij->i", a, b)) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))


def angle_errors(view, light, bounds, body, options, gt, seen, radius: int) -> tuple:
    """(the angles on the surface, those in the first look's map's texels, whether the sample is off the corners, the
    edge samples): one per matched sample."""
    from addon.gpu.visibility import EDGE_MAP
    from addon.warp import compute
    from addon.warp.aliasing import raster_jacobian
    d = seen.edge_directions
    at_edge = np.any(d != 0, axis=1)
    points, normals, d = seen.surface[at_edge].mean(axis=1), seen.normals[at_edge], d[at_edge]
    straight, edge_n, cornered = true_edges(gt)
    pixel, found = nearest_true(view, gt, straight, points, normals, radius)
    points, normals, d, pixel = points[found], normals[found], d[found], pixel[found]
    n_s = edge_n[pixel[:, 0], pixel[:, 1]]
    d_view = raster_jacobian(view.world_to_clip, view.resolution, points)
    truth = np.cross(normals, np.einsum("kij,ki->kj", d_view, n_s))
    setup = compute("uniform", view, light, bounds, replace(options, shadow_map_size=(EDGE_MAP, EDGE_MAP)), body=body)
    in_map = np.full(len(points), np.nan)
    free = np.ones(len(points), dtype=bool)
    for m in setup.maps:
        mine = free & m.contains(points)
        free &= ~mine
        if mine.any():
            jac = raster_jacobian(m.matrix, m.size, points[mine])
            in_map[mine] = line_angle(np.einsum("kij,kj->ki", jac, d[mine]), np.einsum("kij,kj->ki", jac, truth[mine]))
    return line_angle(d, truth), in_map, ~cornered[pixel[:, 0], pixel[:, 1]], int(at_edge.sum())


def timings(frame, region, body, light, bounds, options, repeat: int) -> tuple[float, float]:
    """Median ms of ``shadow_edges`` and of ``at_shadow_edge`` alone (on the first map's samples), ``repeat`` calls."""
    from addon.gpu import visibility as V
    from addon.warp import compute
    whole, part = [], []
    setup = compute("uniform", frame.view, light, bounds, replace(options, shadow_map_size=(V.EDGE_MAP, V.EDGE_MAP)),
                    body=body)
    depth = frame.probe_depths(setup, body)[0]
    points = region.surface.mean(axis=1)
    mine = setup.maps[0].contains(points)
    normals = region.normals * np.sign(np.einsum("ij,ij->i", region.normals, (
        -frame.view.direction[None] if frame.view.orthographic else frame.view.position - points)))[:, None]
    for _ in range(repeat):
        t = time.perf_counter()
        V.shadow_edges(frame, region, body, light, bounds, options)
        whole.append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        V.at_shadow_edge(setup.maps[0], depth, points[mine], normals[mine], light)
        part.append(1e3 * (time.perf_counter() - t))
    return statistics.median(whole), statistics.median(part)


def summary(angles: np.ndarray) -> str:
    a = angles[np.isfinite(angles)]
    if not len(a):
        return "none"
    return (f"median {np.median(a):5.2f}°, p90 {np.percentile(a, 90):5.2f}°, within 2° {np.mean(a <= 2):.2f}, "
            f"5° {np.mean(a <= 5):.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.edge_directions", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="", help="comma-separated scene names (sample or box scenes)")
    ap.add_argument("--generated", type=int, default=0, help="also this many generated box scenes of each of --seeds")
    ap.add_argument("--seeds", default="1", help="comma-separated seeds of the generated scenes")
    ap.add_argument("--kinds", default="", help="only generated scenes whose name holds one of these (comma-separated)")
    ap.add_argument("--resolution", default="640x360", help="render size WxH")
    ap.add_argument("--radius", type=int, default=6, help="pixels from a sample to the true edge that stands for it")
    ap.add_argument("--repeat", type=int, default=0, help="also time the first look, the median of this many calls")
    args = ap.parse_args(argv)
    from bench.rendered_error import _scratch_env
    _scratch_env()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import bpy  # noqa: F401 - Blender before mathutils
    from addon.scene.describe import describe_scene
    from bench.box_scenes import generated_name
    from bench.rendered_error import scene_with_truth
    kinds = [k for k in args.kinds.split(",") if k]
    scenes = [s for s in args.scenes.split(",") if s] + [
        n for s in args.seeds.split(",") for n in (generated_name(int(s), k) for k in range(args.generated))
        if not kinds or any(k in n for k in kinds)]
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    surface, texels, straight, times = [], [], [], []
    for name in scenes:
        dg, geometry, view, light, gt, _ = scene_with_truth(name, resolution)
        _, _, bounds = describe_scene(bpy.context.scene, dg)
        frame, region, body, options, seen = first_look(dg, geometry, view, light, bounds)
        if seen.edge_directions is None:
            print(f"{name:>28}: no first look (nothing casts, or no surface read)", flush=True)
            continue
        on, in_map, off_corners, count = angle_errors(view, light, bounds, body, options, gt, seen, args.radius)
        surface.append(on)
        texels.append(in_map)
        straight.append(off_corners)
        line = f"{name:>28}: {len(on):4d} of {count:4d} edge samples matched; in the map's texels {summary(in_map)}"
        if args.repeat:
            times.append(timings(frame, region, body, light, bounds, options, args.repeat))
            line += f"; first look {times[-1][0]:.1f} ms (at_shadow_edge {times[-1][1]:.2f} ms)"
        print(line, flush=True)
    if surface:
        on, in_map, off = (np.concatenate(x) for x in (surface, texels, straight))
        print(f"{'all':>28}: {len(on)} samples; in the map's texels {summary(in_map)}; on the surface {summary(on)}")
        print(f"{'off corners':>28}: {int(off.sum())} samples (no true corner within {CORNER_PIXELS} px); in the map's "
              f"texels {summary(in_map[off])}; on the surface {summary(on[off])}")
    if times:
        print(f"{'':>28}  first look, sum of per-scene medians {sum(t[0] for t in times):.1f} ms, "
              f"at_shadow_edge {sum(t[1] for t in times):.2f} ms")
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit
