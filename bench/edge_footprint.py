"""What the rendered error follows: the texel's width across the true shadow edges, and σ_max at their corners.

    python -m bench.edge_footprint --scenes forest_side_sun,stage_spot --sizes 2048
    python -m bench.edge_footprint --scenes stage_spot --methods cascade --sizes 1024,2048
    python -m bench.edge_footprint --scenes floor_wall --methods uniform,cascade --sizes 1024,2048,4096 --ties 4
    python -m bench.edge_footprint --scenes floor_wall --methods uniform,cascade --ties 4 --pcf 1   # PCF 2's gain

Renders each scene like ``bench.rendered_error`` (the engine's path, ``LixelSettings`` defaults, only
the method and the map size changed) and sets each method's numbers against uniform's:

* ``p95``: the analytic footprint σ_max at the 95th percentile over the lit points facing the light,
  the number the "warping wins" criterion reads;
* ``straight``: the misclassified pixels at straight true shadow edges and the mean there of
  ``addon.measure.footprint.setup_across_edge_width``, |Jᵀn|, the screen pixels one texel spans
  across the edge (n from ``shadow_edge_normals`` at its default radius: a Sobel normal misread
  gen2_08_low_sun's widths by up to 2x where texels are long on the ground). A map puts each edge on
  its texel grid, so the pixels between the true edge and the texel staircase, |Jᵀn| per pixel of
  edge to first order, are what it gets wrong;
* ``corners``: the misclassified pixels within a pixel of a corner (the edge turns by more than
  :data:`TURN_DEG` within :data:`CORNER_RADIUS` pixels: shadow corners, thin and small shadows),
  where both of the texel's directions count, and the mean σ_max there;
* ``other``: the misclassified pixels elsewhere (away from true edges: depth, bias, coverage);
* ``ties`` (``--ties S``): the true edge pixels whose centre the edge passes within a fraction of a pixel
  (between 7 and 9 of the S x S rays of a ground truth cast S times finer are shadowed), and how many of each
  method's wrong pixels are these: a map whose edge errs by more than that distance gets such a pixel wrong about
  as often as a map with coarser texels, so where ties make most of the wrong pixels, the count stops following
  the texel width;
* ``by map``: per map that serves true edge pixels (its role and texels w x h), how many it serves, how many of
  them are wrong, and the mean σ_max there (with ``--ties``, also the ties it serves and gets wrong): a cascade
  whose p95 halves uniform's may still have most of its wrong pixels in a split whose texels are barely finer
  than uniform's; and against uniform on those same pixels: each map's wrong pixels and uniform's there (means over
  the phases) and the width across the edges there in each (floor_wall's cascade at 2048², 16 phases: splits 0-2
  0.43-0.73x uniform's wrong pixels on their pixels, split 3 0.94x at 0.99x uniform's width: 23 of its 52);
* ``at seams`` (a method of several maps): its wrong pixels in the blend bands where the shading mixes two splits'
  shadows, and within two pixels of a change of serving map (a split's end, a cube face's edge), each the mean over
  the phases, beside uniform's on the same pixels: whether the cascade's seams make wrong pixels of their own;
* ``by grid angle``: the straight edge pixels per band of angle to their map's nearest texel axis
  (:data:`ANGLE_BINS`), the wrong ones among them and the mean width across the edge there. The bilinear
  contour of PCF 2 errs across an edge by E|δ| = 0.25 texel on a grid along it, 0.16-0.19 at 20-45° (a
  half-plane's taps), so a map's wrong pixels follow Σ |Jᵀn|·E|δ(angle)| over the edge pixels: 0.64-0.70 x that
  sum for uniform, uniform with 2x the texels and the cascade with and without its turns and 2:1 layouts on
  gen2_08_low_sun, 16 phases (docs/papers.md "The receivers' footprint", session 12). Compare bands of two maps
  only on the same pixels: a band holds different edges in different maps, and the edges with many ties in it
  decide its rate (gen3_04_point_behind_camera's cascade 20-45° band: at its own pixels uniform errs as often);
* ``grid angle``: the straight edges' mean angle to the nearest texel axis of their map, and how many lie within
  :data:`ALIGNED_DEG` of one. The staircase of an edge that runs nearly along a texel axis is long: whole runs
  of its pixels fall on one side of the true edge together, so the same |Jᵀn| gives more wrong pixels, and a
  count that swings more with the grid's phase, than on an edge across the grid's diagonal.

A ratio near the method's width ratio in each class is the texel footprint at work; the p95 ratio
says nothing of edges that lie away from the points that set it.

The counts are those of one phase of each map's texel grid against the pixels; which pixels an edge's
staircase takes changes with it. ``--phases N`` renders each method N times, every map's texel grid
moved by a sub-texel offset (the same texels, a texel more on each side so that no point falls out of
its map; the first phase unmoved, the others an R2 sequence,
the same for every method; a plane map's lixels stay on their pixels), and prints the counts' mean and
spread, the ratio of the means to uniform's and in how many phases the count is at most 0.8x uniform's at
the same phase.

A method ``cascade:<warp>`` is the cascade with every split's warp fixed (``cascade_warp``):
``cascade:uniform``, ``cascade:lispsm``, ``cascade:psm``, ...
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CORNER_RADIUS = 2
TURN_DEG = 35.0
"""An edge pixel is at a corner when the edge normals within CORNER_RADIUS pixels turn by more than TURN_DEG."""
ALIGNED_DEG = 10.0
"""A straight edge within this angle of a texel axis counts as aligned with its map's grid."""
ANGLE_BINS = (0.0, 2.0, 5.0, 10.0, 20.0, 45.0)
"""Degrees to the nearest texel axis by which the straight edge pixels are also counted, wrong or not, with their mean
width across the edge: whether the wrong pixels per edge pixel follow that width alike at every angle."""


def corners(edges: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """The edge pixels where the true edge turns (see :data:`TURN_DEG`); ``normals`` from ``shadow_edge_normals``
    at radius 1."""
    h, w = edges.shape
    r = CORNER_RADIUS
    n = np.where(edges[..., None], np.nan_to_num(normals), 0.0)
    pad = np.pad(n, ((r, r), (r, r), (0, 0)))
    ok = np.pad(edges, r)
    least = np.ones((h, w))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            other = pad[r + dy:r + dy + h, r + dx:r + dx + w]
            cos = np.where(ok[r + dy:r + dy + h, r + dx:r + dx + w], np.einsum("ijk,ijk->ij", n, other), 1.0)
            least = np.minimum(least, cos)
    return edges & (least < math.cos(math.radians(TURN_DEG)))


def grid_angle(view, shadow_map, points, normals, edge_normals) -> np.ndarray:
    """Degrees (0..45) between shadow edges with unit screen normals ``edge_normals`` at (N, 3) surface ``points``
    and the nearest texel axis of ``shadow_map``: the edge's normal in texels is Jᵀn (J = G·H⁻¹, pixels per texel,
    ``addon.measure.footprint.across_edge_width``). NaN where w <= 0 or the surface is edge-on to the map."""
    from addon.measure.footprint import tangent_basis
    from addon.warp.aliasing import raster_jacobian
    t = tangent_basis(normals)
    g = raster_jacobian(view.world_to_clip, view.resolution, points) @ t
    h = raster_jacobian(shadow_map.matrix, shadow_map.size, points) @ t
    ok = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(h), axis=(1, 2)) & (np.abs(np.linalg.det(h)) > 0)
    out = np.full(len(g), np.nan)
    n_texels = np.einsum("nij,ni->nj", g[ok] @ np.linalg.inv(h[ok]), np.asarray(edge_normals)[ok])
    a = np.degrees(np.arctan2(np.abs(n_texels[:, 1]), np.abs(n_texels[:, 0])))
    out[ok] = np.minimum(a, 90.0 - a)
    return out


def method_settings(method: str, size: int, pcf: int = 0):
    """``bench.rendered_error.default_settings``; ``cascade:<warp>`` fixes the cascade's ``cascade_warp``; ``pcf``
    (0: the default) the PCF kernel, to tell what PCF 2's bilinear taps gain on each map over PCF 1."""
    from bench.rendered_error import default_settings
    name, _, warp = method.partition(":")
    settings = default_settings(name, size)
    settings = settings if not pcf else dataclasses.replace(
        settings, shadow=dataclasses.replace(settings.shadow, pcf_kernel=pcf))
    return settings if not warp else dataclasses.replace(
        settings, warp=dataclasses.replace(settings.warp, cascade_warp=warp))


def phases(count: int) -> np.ndarray:
    """(count, 2) sub-texel offsets: (0, 0), then the R2 sequence (Roberts 2018) in [0, 1)²."""
    g = 1.32471795724474602596                                  # the plastic number
    k = np.arange(1, count)[:, None]
    return np.vstack([[0.0, 0.0], (0.5 + k * np.array([1 / g, 1 / g ** 2])) % 1.0])


def shifted(setup, offset):
    """``setup`` with every map's texel grid moved by ``offset`` texels (0..1 each way) and grown by one texel on
    each side, so that the grid moves and the window still holds all it held: the same texels in the world, the map
    ``size + 2`` texels, NDC x, y -> (x·size + 2·offset) / (size + 2). Moving the window alone opened gaps a fraction
    of a texel wide between a point light's cube faces, and between a cascade's splits, that no map served
    (point_low_in_view's cascade 2048², grid phase 7: 7 of its 66 wrong pixels). Not a plane map's (a map with a
    region): its lixels are placed on the pixels (Chong-Gortler §2), so its grid has no free phase, and moved it
    tests each pixel a fraction of a lixel away (gen3_03_spot plane_optimal 2048²: 74 wrong pixels as computed,
    74..442 over 8 phases with the plane map moved)."""
    maps = []
    for m in setup.maps:
        if m.region is not None:
            maps.append(m)
            continue
        size = np.asarray(m.size, dtype=np.float64)
        move = np.eye(4)
        move[[0, 1], [0, 1]] = size / (size + 2.0)
        move[:2, 3] = 2.0 * np.asarray(offset, dtype=np.float64) / (size + 2.0)
        maps.append(dataclasses.replace(m, matrix=move @ m.matrix, size=tuple(int(s) + 2 for s in m.size)))
    return dataclasses.replace(setup, maps=maps)


@contextmanager
def grid_phase(offset):
    """The render engine's maps moved by ``offset`` texels while inside (the warp cache cleared on both sides)."""
    import addon.render.engine as engine
    from addon.render.warp_cache import shared_warps
    fit = engine.fit_warp

    def fit_shifted(*args, **kwargs):
        body, setup, seconds = fit(*args, **kwargs)
        return body, shifted(setup, offset), seconds
    shared_warps().clear()
    engine.fit_warp = fit_shifted
    try:
        yield
    finally:
        engine.fit_warp = fit
        shared_warps().clear()


def ties(name: str, view, light, edges: np.ndarray, supersample: int) -> np.ndarray:
    """The ``edges`` pixels whose centre the true shadow edge passes close to: ``bench.report.ground_truth`` of
    ``view`` at ``supersample`` times its resolution each way, and between 7/16 and 9/16 of each pixel's rays
    shadowed (the same scene, whose bounds scale its rays' offsets)."""
    import bpy
    from addon.scene.describe import describe_scene
    from addon.scene.geometry import GeometryCache
    from bench.report import ground_truth as G
    dg = bpy.context.evaluated_depsgraph_get()
    _, _, bounds = describe_scene(bpy.context.scene, dg)
    w, h = view.resolution
    fine = G.ground_truth(dataclasses.replace(view, resolution=(w * supersample, h * supersample)), light,
                          G.build_bvh(G.world_triangles(GeometryCache().update(dg))), bounds.scale())
    shadowed = fine.shadow.reshape(h, supersample, w, supersample).mean(axis=(1, 3))
    return edges & (np.abs(shadowed - 0.5) <= 1.0 / 16.0)


def _mean(values) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if len(v) else float("nan")


def measure_scene(name: str, methods, sizes, resolution, phase_count: int = 1, supersample: int = 0,
                  pcf: int = 0) -> list[dict]:
    """One row per method and size: wrong pixels by class, the p95, the mean widths at straight edges and corners,
    the wrong pixels at each of ``phase_count`` grid phases (the first: the maps as computed) and, with
    ``supersample``, at :func:`ties`."""
    from addon.measure import classify, footprint_stats, setup_footprints
    from addon.measure.errors import dilate, shadow_edges
    from addon.measure.footprint import per_serving_map, setup_across_edge_width, shadow_edge_normals
    from addon.render.engine import render_depsgraph
    from bench.rendered_error import scene_with_truth
    from bench.report.analysis import lit_facing
    from bench.report.lixel import READ
    from bench.report.run import comparable_mask

    dg, geometry, view, light, gt, _ = scene_with_truth(name, resolution)
    lit = lit_facing(gt, light)
    turning = shadow_edge_normals(gt.shadow, gt.valid, 1)          # Sobel: turns within CORNER_RADIUS
    edge_n = shadow_edge_normals(gt.shadow, gt.valid)              # straight edges' normals within a degree or two
    edges = shadow_edges(gt.shadow, gt.valid) & np.isfinite(turning[..., 0]) & np.isfinite(edge_n[..., 0])
    corner = corners(edges, turning)
    near_corner = dilate(corner, 1)
    straight = edges & ~near_corner
    tied = ties(name, view, light, edges, supersample) if supersample else None
    rows = []
    for method in methods:
        for size in sizes:
            settings = method_settings(method, size, pcf)
            last = render_depsgraph(dg, resolution, settings=settings, read=READ | {"eye_depth"})
            setup, result = last["setup"], last["result"]
            shadow, counted = result.shadow_raw >= 0.5, comparable_mask(gt, result)
            wrong = counted & (shadow != gt.shadow)
            fp, _ = setup_footprints(view, setup, gt.points[lit], gt.normals[lit])
            at_corners, _ = setup_footprints(view, setup, gt.points[corner], gt.normals[corner])
            across = setup_across_edge_width(view, setup, gt.points[straight], gt.normals[straight], edge_n[straight])
            angle = per_serving_map(view, setup, gt.points[straight], lambda m, p, n, e: grid_angle(view, m, p, n, e),
                                    gt.normals[straight], edge_n[straight])
            by_phase, wrong_by_phase = [classify(shadow, gt.shadow, counted, 2).errors], [wrong]
            for offset in phases(phase_count)[1:]:
                with grid_phase(offset):
                    moved = render_depsgraph(dg, resolution, settings=settings, read=READ)["result"]
                by_phase.append(classify(moved.shadow_raw >= 0.5, gt.shadow, comparable_mask(gt, moved), 2).errors)
                wrong_by_phase.append(comparable_mask(gt, moved) & ((moved.shadow_raw >= 0.5) != gt.shadow))
            rows.append({"scene": name, "method": method, "size": size, "wrong": by_phase[0], "phases": by_phase,
                         "straight": int((wrong & straight).sum()), "corners": int((wrong & near_corner).sum()),
                         "p95": footprint_stats(fp).p95, "across": _mean(across), "corner_smax": _mean(at_corners),
                         "grid_angle": _mean(angle), "aligned": int(np.sum(angle <= ALIGNED_DEG)),
                         "by_angle": by_angle(angle, wrong[straight], across),
                         "by_map": by_map(view, setup, result.map_index, edges & counted, wrong, gt, tied),
                         "ties": None if tied is None else (int((wrong & tied).sum()), int((tied & counted).sum()),
                                                            int((wrong & edges & ~tied).sum())),
                         "setup": setup, "served": [edges & counted & (result.map_index == i)
                                                    for i in range(len(setup.maps))], "wrong_by_phase": wrong_by_phase,
                         "seams": [k & counted for k in seams(setup, result)]})
    for r in rows:
        u = next(u for u in rows if u["method"] == "uniform" and u["size"] == r["size"])
        r["against_uniform"] = [against_uniform(view, gt, edge_n, px, r, u) if px.any() else None for px in r["served"]]
        r["at_seams"] = [(int(k.sum()), *(float(np.mean([w[k].sum() for w in x["wrong_by_phase"]])) for x in (r, u)))
                         for k in r["seams"]] if len(r["setup"].maps) > 1 else None
    return rows


def seams(setup, result) -> tuple:
    """(the pixels in a blend band, those within ``CORNER_RADIUS`` pixels of a change of serving map but in no band):
    a cascade's seams. A band is where the shading pass (shade_frag.glsl) mixes map j's shadow into a farther map's:
    the eye depth within ``blend_band`` past the end of j's ``view_depth_range``; a change is a split's end, a cube
    face's edge or a silhouette between surfaces that different maps serve."""
    from addon.measure.errors import dilate
    index, band = result.map_index, np.zeros(result.map_index.shape, dtype=bool)
    for j, m in enumerate(setup.maps):
        if m.blend_band > 0.0 and m.view_depth_range is not None:
            past = result.eye_depth - m.view_depth_range[1]
            band |= (index > j) & (past > 0.0) & (past < m.blend_band)
    change = np.zeros_like(band)
    rows, cols = index[1:] != index[:-1], index[:, 1:] != index[:, :-1]
    change[1:] |= rows
    change[:-1] |= rows
    change[:, 1:] |= cols
    change[:, :-1] |= cols
    return band, dilate(change, CORNER_RADIUS) & ~band


def against_uniform(view, gt, edge_n, pixels, row, uniform) -> tuple:
    """At the true edge pixels one of ``row``'s maps serves (as computed): its wrong pixels there and uniform's, each
    the mean over the grid phases, and the mean width across the straight edges there, its own and uniform's: whether
    that map's texels gain on uniform's where its own edges are (a cascade's far split may hold most of the wrong
    pixels at uniform's width: floor_wall's split 3, docs/papers.md)."""
    from addon.measure.footprint import setup_across_edge_width
    p, n, e = gt.points[pixels], gt.normals[pixels], edge_n[pixels]
    return (float(np.mean([w[pixels].sum() for w in row["wrong_by_phase"]])),
            float(np.mean([w[pixels].sum() for w in uniform["wrong_by_phase"]])),
            _mean(setup_across_edge_width(view, row["setup"], p, n, e)),
            _mean(setup_across_edge_width(view, uniform["setup"], p, n, e)))


def by_angle(angle: np.ndarray, wrong: np.ndarray, across: np.ndarray) -> list[tuple]:
    """Per bin of ``ANGLE_BINS`` (the last closed): (straight edge pixels, wrong ones, mean width across there)."""
    k = np.digitize(np.nan_to_num(angle, nan=-1.0), ANGLE_BINS[1:-1])
    return [(int(np.sum(m)), int(np.sum(wrong & m)), _mean(across[m])) for m in (np.isfinite(angle) & (k == b)
                                                                               for b in range(len(ANGLE_BINS) - 1))]


def by_map(view, setup, map_index, edges, wrong, gt, tied=None) -> list[tuple]:
    """Per map that serves a true edge pixel: (role, edge pixels it serves, wrong pixels among them, mean σ_max at
    them, and with ``tied`` the :func:`ties` it serves and the wrong ones among them, else None): where the wrong
    pixels lie, and how fine the texels are there (the p95 may be set by other maps)."""
    from addon.measure import setup_footprints
    out = []
    for i, m in enumerate(setup.maps):
        mine = edges & (map_index == i)
        if mine.any():
            fp, _ = setup_footprints(view, setup, gt.points[mine], gt.normals[mine], np.full(int(mine.sum()), i))
            out.append((f"{m.role} {m.size[0]}x{m.size[1]}", int(mine.sum()), int((wrong & mine).sum()), _mean(fp),
                        None if tied is None else (int((tied & mine).sum()), int((tied & wrong & mine).sum()))))
    return out


def table(rows: list[dict]) -> list[str]:
    """The rows against uniform's at the same scene and size: each count's ratio beside its width's ratio."""
    by = {(r["scene"], r["method"], r["size"]): r for r in rows}
    lines = []
    for r in rows:
        u = by.get((r["scene"], "uniform", r["size"]))
        if u is None:
            continue
        def ratio(key):
            return r[key] / u[key] if u[key] else float("nan")
        other = r["wrong"] - r["straight"] - r["corners"]
        lines.append(f"{r['scene']:>20} {r['method']:>13} {r['size']:5d}: {r['wrong']:5d} wrong ({ratio('wrong'):.2f}x "
                     f"uniform's; p95 {ratio('p95'):.2f}x) = straight edges {r['straight']:4d} ({ratio('straight'):.2f}x; "
                     f"across-edge width {r['across']:.3f} px, {ratio('across'):.2f}x) + corners {r['corners']:4d} "
                     f"({ratio('corners'):.2f}x; σ_max {r['corner_smax']:.3f} px, {ratio('corner_smax'):.2f}x) "
                     f"+ other {other}; straight edges' grid angle {r['grid_angle']:.1f}°, {r['aligned']} "
                     f"within {ALIGNED_DEG:.0f}°")
        if r["ties"] is not None:
            at, of, elsewhere = r["ties"]
            lines.append(f"{'':>42}at ties {at} of {of} ({at / max(of, 1):.2f}); at other edge pixels {elsewhere}")
        lines.append(f"{'':>42}by grid angle (straight edge pixels, wrong, mean width across): " + "; ".join(
            f"{a:.0f}-{b:.0f}° {n}, {w}, {x:.2f} px" for (a, b), (n, w, x) in zip(zip(ANGLE_BINS, ANGLE_BINS[1:]),
                                                                              r["by_angle"])))
        lines.append(f"{'':>42}by map (edge pixels, wrong, mean σ_max there): " + "; ".join(
            f"{role} {n}, {w}, {smax:.2f} px" + (f", ties {t[1]} of {t[0]}" if t else "")
            for role, n, w, smax, t in r["by_map"]))
        if r["method"] != "uniform":
            lines.append(f"{'':>42}by map against uniform at the edge pixels it serves (wrong, uniform's wrong there, "
                         f"mean over phases; width across, uniform's there): " + "; ".join(
                             f"{role} {a[0]:.1f}, {a[1]:.1f} ({a[0] / max(a[1], 1e-9):.2f}x); {a[2]:.3f}, {a[3]:.3f} px "
                             f"({a[2] / a[3]:.2f}x)" for (role, *_), a in zip(
                                 [m for m in r["by_map"]], [a for a in r["against_uniform"] if a is not None])))
        if r["at_seams"] is not None:
            (nb, b, ub), (nc, c, uc) = r["at_seams"]
            lines.append(f"{'':>42}at seams (wrong, mean over phases; uniform's on the same pixels): blend bands "
                         f"{b:.1f}, {ub:.1f} of {nb} px; within {CORNER_RADIUS} px of a change of map {c:.1f}, {uc:.1f} "
                         f"of {nc} px")
        if len(r["phases"]) > 1:
            v, uv = np.array(r["phases"]), np.array(u["phases"])
            lines.append(f"{'':>42}over {len(v)} grid phases: {v.mean():.1f} ± {v.std(ddof=1):.1f} wrong "
                         f"({v.min()}..{v.max()}), {v.mean() / uv.mean():.2f}x uniform's mean; at most 0.8x "
                         f"uniform's in {int(np.sum(v <= 0.8 * uv))} of {len(v)}")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.edge_footprint", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", required=True, help="comma-separated scene names (sample or box scenes)")
    ap.add_argument("--methods", default=None, help="comma-separated methods (default: all)")
    ap.add_argument("--sizes", default="2048", help="comma-separated map sizes")
    ap.add_argument("--resolution", default="640x360", help="render size WxH")
    ap.add_argument("--phases", type=int, default=1, help="grid phases per method and size (1: as computed)")
    ap.add_argument("--ties", type=int, default=0, metavar="S",
                    help="also count the wrong pixels at ties, from a ground truth S times finer each way (0: off)")
    ap.add_argument("--pcf", type=int, default=0, metavar="K", help="render with a K x K PCF kernel (0: the default)")
    args = ap.parse_args(argv)
    from bench.rendered_error import _scratch_env
    _scratch_env()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import bpy  # noqa: F401 - Blender before mathutils
    from addon.warp import METHODS
    methods = args.methods.split(",") if args.methods else list(METHODS)
    methods = methods if "uniform" in methods else ["uniform", *methods]
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    rows = []
    for name in args.scenes.split(","):
        rows += measure_scene(name, methods, [int(s) for s in args.sizes.split(",")], resolution, args.phases,
                              args.ties, args.pcf)
    print("\n".join(table(rows)), flush=True)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit
