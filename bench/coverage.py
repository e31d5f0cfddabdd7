"""Coverage only, every method, on the judge's generated configurations (issues 12 and 15).

    python -m bench.coverage [--seeds 8,9,10] [--generated 60] [--methods uniform,lispsm,...] [--json OUT]

For each generated configuration (``bench.cascade.generated_configurations``) and method, with the defaults and
1024² maps: the visible points no map serves, the casters on their shadow rays outside the serving map, and the
casters losing the depth test (``addon.measure.box_scene.judge`` at the judge's 96 x 54 pixels), and whether the
visible region (``visibility.region_from_boxes``, the CLI's) holds every visible point of a finer, jittered grid.
Prints the configurations with a miss and a summary; the judge's footprints and the reference PSSM are left to
``bench.cascade judge``, so a sweep over many seeds stays quick.
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from addon.measure.box_scene import judge, visible_points
from addon.warp import METHODS, EmptyBodyError, WarpOptions, compute, region_from_boxes
from bench.cascade import generated_configurations


def region_misses(view, scene, samples=(241, 137)) -> int:
    """Visible points of a ``samples`` grid (finer than the region's rays, on none of them) the region lacks."""
    points, _ = visible_points(view, scene, samples)
    return int((~region_from_boxes(view, scene).contains(view, points)).sum())


def sweep(seeds, generated: int, methods, log=print) -> list:
    rows = []
    for seed in seeds:
        for name, (view, light, scene) in generated_configurations(generated, seed).items():
            row = {"seed": seed, "config": name, "region_misses": region_misses(view, scene)}
            for method in methods:
                try:
                    setup = compute(method, view, light, scene, WarpOptions(shadow_map_size=1024))
                except EmptyBodyError:
                    continue
                j = judge(view, light, scene, setup)
                row[method] = (j.uncovered, j.casters_uncovered, j.depth_order_wrong, j.visible)
            rows.append(row)
            bad = {m: row[m] for m in methods if m in row and any(row[m][:3])}
            if bad or row["region_misses"]:
                log(f"seed {seed} {name}: region misses {row['region_misses']}; "
                    + ", ".join(f"{m} {u} visible, {c} casters uncovered, {d} depth order" for m, (u, c, d, _) in bad.items()))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="8,9,10,11,12")
    ap.add_argument("--generated", type=int, default=60)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    methods = args.methods.split(",")
    rows = sweep([int(s) for s in args.seeds.split(",")], args.generated, methods)
    for m in methods:
        runs = [r[m] for r in rows if m in r]
        missed = [r for r in runs if any(r[:3])]
        worst = min((1 - r[0] / r[3] for r in runs if r[3]), default=1.0)
        print(f"{m:14s} {len(runs) - len(missed):4d}/{len(runs)} configurations covered; least visible share "
              f"served {worst:.4f}")
    print(f"region: {sum(r['region_misses'] == 0 for r in rows)}/{len(rows)} hold every visible point "
          f"({int(np.sum([r['region_misses'] for r in rows]))} missed)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
