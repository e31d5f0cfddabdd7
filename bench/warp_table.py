"""The analytic comparison of every method on the bundled example configs.

    python -m bench.warp_table [CONFIG.json ...] [--size 1024] [--markdown]

For each config and method: θ, n_opt or λ, the number of maps, coverage as an
outside evaluation measures it (``addon.measure.box_scene.judge``: visible
points ray-cast from camera pixels, their casters on the shadow rays) and the
texel footprint (screen pixels per texel) at p95 and max, next to the CPU time
of B plus the method. Plain Python and numpy; no Blender needed.
"""
from __future__ import annotations

import argparse
import glob
import json
import math
import time
from pathlib import Path

from addon.measure.box_scene import judge
from addon.warp import METHODS, EmptyBodyError, WarpError, WarpOptions, compute, intersection_body
from addon.cli.config import parse_config

ROOT = Path(__file__).resolve().parents[1]


def _time_us(fn, repeat: int = 5) -> float:
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best * 1e6


def rows_for(path: Path, size: int | None = None) -> list[dict]:
    view, light, scene, options = parse_config(json.loads(path.read_text()))
    if size:
        options = WarpOptions(**{**options.__dict__, "shadow_map_size": (size, size)})
    out = []
    try:
        body = intersection_body(view, light, scene)
    except EmptyBodyError as exc:
        return [{"config": path.stem, "method": m, "error": f"empty B: {exc}"} for m in METHODS]
    for name in METHODS:
        row = {"config": path.stem, "method": name}
        try:
            setup = compute(name, view, light, scene, options, body=body)
            row["us"] = _time_us(lambda: compute(name, view, light, scene, options))
            d = setup.diagnostics
            row["theta_deg"] = None if d.theta is None else math.degrees(d.theta)
            row["n_opt"], row["lambda"] = d.n_opt, d.lam
            row["maps"] = len(setup.maps)
            j = judge(view, light, scene, setup)
            row["covering"] = j.covering
            row["uncovered"] = j.uncovered + j.casters_uncovered + j.depth_order_wrong
            row["p95"], row["max"] = j.footprint_p95, j.footprint_max
            row["fallbacks"] = len(d.fallbacks)
        except WarpError as exc:
            row["error"] = str(exc)
        out.append(row)
    return out


def _fmt(v, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def render(rows: list[dict], markdown: bool = False) -> str:
    head = ["config", "method", "θ°", "n_opt", "λ", "maps", "coverage", "p95 px/texel", "max px/texel", "µs (B+warp)"]
    lines = []
    for r in rows:
        if "error" in r:
            cells = [r["config"], r["method"], "", "", "", "", "failed: " + r["error"], "", "", ""]
        else:
            cov = "100%" if r["covering"] else f"{r['uncovered']} missed"
            cells = [r["config"], r["method"], _fmt(r["theta_deg"], ".1f"), _fmt(r["n_opt"], ".3g"),
                     _fmt(r["lambda"], ".3g"), str(r["maps"]), cov, _fmt(r["p95"], ".2f"), _fmt(r["max"], ".1f"),
                     _fmt(r["us"], ".0f")]
        lines.append(cells)
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        out += ["| " + " | ".join(c) + " |" for c in lines]
        return "\n".join(out)
    widths = [max(len(h), *(len(c[i]) for c in lines)) for i, h in enumerate(head)]
    fmt = "  ".join("{:<%d}" % w for w in widths)
    return "\n".join([fmt.format(*head), fmt.format(*("-" * w for w in widths))] + [fmt.format(*c) for c in lines])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.warp_table", description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="*", type=Path)
    ap.add_argument("--size", type=int, default=None, help="shadow map size (default: each config's)")
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args(argv)
    paths = args.configs or [Path(p) for p in sorted(glob.glob(str(ROOT / "examples" / "*.json")))]
    rows = [r for p in paths for r in rows_for(p, args.size)]
    print(render(rows, args.markdown))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
