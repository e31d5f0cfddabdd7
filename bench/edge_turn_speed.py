"""What weighing the shadow edges costs per change of view: PSM's edge turn (``methods.psm.turned_fit``, 36 turns
scored by ``partition.receivers.filter_losses``) and the cascade's pick (``Trials.candidates``: its candidates'
``footprints`` and ``filter_losses``), against the number of edge samples the first look gave.

    OPENBLAS_NUM_THREADS=1 python -m bench.edge_turn_speed [--edges 0 500 2000 4000] [--repeat 15]

The inputs: ``tests/warp/test_psm_edge_axes.py``'s gen46_08_low_sun as the render engine gave it to the warp core,
its 500 lit points as the edge samples (tiled for more), each along a random direction in its surface (the
cascade's receivers are the same points). Two paths to the maps' raster Jacobians are timed in turn, call by call
(a burst of load falls on both alike): ``per_map_jacobians``, one ``raster_jacobian`` per distinct matrix and
D_M·vectors per map (session 21's way), and ``receivers.jacobians``, one per group of maps that differ by a map of
x/w, y/w (PSM's turns, the cascade's ``turned`` maps) and a 2x2 per map. Per method and count: the median process
CPU time per ``compute`` call and of the part in it (``turned_fit``; ``candidates``, every call summed) for each
path, the part's ratio, and whether both paths chose the same matrices (bit for bit, or within how much).
"""
from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def per_map_jacobians(maps: list, points: np.ndarray, vectors: np.ndarray | None = None) -> np.ndarray:
    """Session 21's ``partition.receivers.jacobians``: a ``raster_jacobian`` of each distinct matrix, then each map's
    D_M·``vectors`` (footprints' and filter_losses' products, made per map)."""
    from addon.warp.aliasing import raster_jacobian

    first, index = np.unique([id(m.matrix) for m in maps], return_index=True, return_inverse=True)[1:]
    d = raster_jacobian([maps[i].matrix for i in first], [(2, 2)] * len(first), points)[index]
    d = d * np.array([m.size for m in maps], dtype=np.float64)[:, None, :, None] / 2.0
    return d if vectors is None else d @ vectors


def edged(body, points: np.ndarray, normals: np.ndarray, directions: np.ndarray, n: int):
    """``body`` whose first look saw ``n`` shadow-edge samples: the points, tiled, along ``directions``."""
    k = np.resize(np.arange(len(points)), n)
    seen = replace(body.visible, surface=np.stack([points[k], points[k]], 1), normals=normals[k],
                   edge_directions=directions[k])
    return replace(body, visible=seen)


def timed(owner, name: str, spent: list):
    """``owner.name`` replaced by itself adding its process CPU time to ``spent[0]``; returns the original."""
    original = getattr(owner, name)

    def counted(*args, **kwargs):
        start = time.process_time()
        try:
            return original(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - start
    setattr(owner, name, counted)
    return original


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edges", type=int, nargs="+", default=[0, 500, 2000, 4000])
    parser.add_argument("--methods", nargs="+", default=["psm", "cascade"])
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args(argv)
    sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "warp")]
    from addon.warp import compute
    from addon.warp.partition import receivers
    from test_psm_edge_axes import low_sun_with_lit_points
    parts = {"psm": (importlib.import_module("addon.warp.methods.psm"), "turned_fit"),
             "cascade": (importlib.import_module("addon.warp.methods.cascade").Trials, "candidates")}

    view, light, scene, options, body, points, normals = low_sun_with_lit_points()
    directions = np.cross(normals, np.random.default_rng(0).normal(size=normals.shape))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    paths, grouped = {"per map": per_map_jacobians, "grouped": receivers.jacobians}, receivers.jacobians
    print(f"gen46_08_low_sun, {options.shadow_map_size[0]}², medians of {args.repeat} interleaved calls, process CPU ms")
    print(f"{'method':8s} {'edges':>5s} {'compute: per map':>16s} {'grouped':>8s}   {'part: per map':>13s} {'grouped':>8s}"
          f" {'ratio':>6s}  matrices")
    for method in args.methods:
        spent = [0.0]                             # (the part's time in the call: every call of it summed)
        original = timed(*parts[method], spent)
        try:
            for n in args.edges:
                looked, times, chosen = edged(body, points, normals, directions, n), {k: ([], []) for k in paths}, {}
                for _ in range(args.repeat + 1):                          # (the first of each: a warm-up)
                    for name, path in paths.items():
                        receivers.jacobians, spent[0] = path, 0.0
                        start = time.process_time()
                        setup = compute(method, view, light, scene, options, body=looked)
                        times[name][0].append(time.process_time() - start)
                        times[name][1].append(spent[0])
                        chosen[name] = np.array([m.matrix for m in setup.maps])
                (before, before_part), (after, after_part) = (
                    [statistics.median(t[1:]) * 1e3 for t in times[k]] for k in paths)
                a, b = chosen.values()
                same = "identical" if np.array_equal(a, b) else \
                    f"within {np.abs(a - b).max() / np.abs(a).max():.1e}" if a.shape == b.shape else "differ"
                ratio = f"{before_part / after_part:6.2f}" if after_part > 0 else "     -"
                print(f"{method:8s} {n:5d} {before:16.2f} {after:8.2f}   {before_part:13.2f} {after_part:8.2f} {ratio}  {same}")
        finally:
            receivers.jacobians = grouped
            setattr(*parts[method], original)
    return 0


if __name__ == "__main__":
    sys.exit(main())
