"""The golden comparison: every method's maps on the bundled examples, the hard
cases and the bench scene, stored once and compared up to rounding.

    python -m tests.warp.golden            # compare the working tree with golden.json.gz
    python -m tests.warp.golden --write    # store the working tree's maps as the new golden

A refactoring must leave the golden unchanged. A change that means to change
matrices (a new default, a fixed bug) rewrites the golden in the same commit and
says why in the message. Each configuration is computed with the options written
here (``OPTIONS``), so a later change of ``WarpOptions``' defaults that keeps the
old behaviour reachable only needs those options named here.

Compared per map: role, size, depth test, the matrix (entries within 1e-6 of its
largest entry), ``view_depth_range``, ``depth_row`` and the region; per setup:
θ, γ, n_opt, λ and the fallbacks' names. B's vertices are not compared: their
order is not part of the contract.
"""
from __future__ import annotations

import argparse
import gzip
import json
import math
import sys
from pathlib import Path
from typing import Iterator

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).with_name("golden.json.gz")

OPTIONS: dict = {"focus": "view", "lambda_guard": "off", "linear_z": False}
"""WarpOptions fields every golden configuration is computed with (besides its own):
B over the whole view frustum and every λ as its paper gives it, the behaviour
before issue 12 (the golden passes its own unfocused B, so ``focus`` only
documents that), and the matrices' hyperbolic depth (``linear_z`` became the
default with the linear depth rows, issue 12; the ``:linear_z`` configurations
check the rows)."""

RELATIVE = 1e-6

PENDING: frozenset = frozenset()
"""Methods not in the golden yet (none: the cascade, issue 15, joined once its
split scheme and warp choice settled)."""


def configurations() -> Iterator[tuple[str, object, object, object, object]]:
    """(name, view, light, scene, options) for every golden configuration."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(Path(__file__).parent))
    from addon.warp import WarpOptions
    from addon.cli.config import parse_config
    from bench.warp_speed import LIGHTS, city_scene, street_view
    from hard_cases import EMPTY_CASES, HARD_CASES

    for path in sorted((ROOT / "examples").glob("*.json")):
        view, light, scene, options = parse_config(json.loads(path.read_text()))
        yield f"example:{path.stem}", view, light, scene, options.__class__(**{**_fields(options), **OPTIONS})
    for name, (view, light, scene) in HARD_CASES.items():
        if name in EMPTY_CASES:
            continue
        yield f"hard:{name}", view, light, scene, WarpOptions(**{"shadow_map_size": (1024, 1024), **OPTIONS})
        if name in ("sun_behind_camera", "point_light_behind_camera", "spot_over_scene"):
            yield (f"hard:{name}:linear_z", view, light, scene,
                   WarpOptions(**{"shadow_map_size": (1024, 1024), **OPTIONS, "linear_z": True}))
    scene = city_scene(2_000)
    for name, light in LIGHTS.items():
        yield f"bench:{name}", street_view(), light, scene, WarpOptions(**OPTIONS)


def _fields(options) -> dict:
    import dataclasses
    return {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}


def _floats(a) -> list | None:
    if a is None:
        return None
    return [float(f"{v:.12g}") for v in np.asarray(a, dtype=np.float64).ravel()]


def _angle(v) -> float | None:
    return None if v is None or not math.isfinite(v) else float(f"{v:.12g}")


def snapshot() -> dict:
    """Every golden configuration's setups as plain data."""
    from addon.warp import METHODS, WarpError, compute, intersection_body

    out: dict = {}
    for name, view, light, scene, options in configurations():
        body = intersection_body(view, light, scene)
        for method in METHODS:
            if method in PENDING:
                continue
            key = f"{name}/{method}"
            try:
                setup = compute(method, view, light, scene, options, body=body)
            except WarpError as exc:
                out[key] = {"error": type(exc).__name__}
                continue
            d = setup.diagnostics
            out[key] = {
                "maps": [{
                    "role": m.role, "size": [int(m.size[0]), int(m.size[1])], "depth_test": m.depth_test,
                    "matrix": _floats(m.matrix), "depth_row": _floats(m.depth_row),
                    "view_depth_range": _floats(m.view_depth_range),
                    "region": None if m.region is None else _floats(np.concatenate(
                        [np.asarray(m.region.normal, float), [m.region.offset],
                         np.asarray(m.region.polygon, float).ravel()])),
                } for m in setup.maps],
                "theta": _angle(d.theta), "gamma": _angle(d.gamma),
                "n_opt": _angle(d.n_opt), "lam": _angle(d.lam),
                "fallbacks": sorted({what for what, _ in d.fallbacks}),
            }
    return out


def _close(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return False
    scale = max(float(np.max(np.abs(b))) if b.size else 0.0, 1e-300)
    return bool(np.all(np.abs(a - b) <= RELATIVE * scale))


def _scalar_close(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= RELATIVE * max(abs(a), abs(b), 1.0)


def differences(now: dict, golden: dict) -> list[str]:
    """One line per setup that differs from the golden (empty: the same up to rounding)."""
    lines = []
    for key in sorted(set(now) | set(golden)):
        a, b = now.get(key), golden.get(key)
        if a is None or b is None:
            lines.append(f"{key}: {'new' if b is None else 'missing'}")
            continue
        if "error" in a or "error" in b:
            if a.get("error") != b.get("error"):
                lines.append(f"{key}: error {a.get('error')} (golden {b.get('error')})")
            continue
        if len(a["maps"]) != len(b["maps"]):
            lines.append(f"{key}: {len(a['maps'])} maps (golden {len(b['maps'])})")
            continue
        for i, (ma, mb) in enumerate(zip(a["maps"], b["maps"])):
            for field in ("role", "size", "depth_test"):
                if ma[field] != mb[field]:
                    lines.append(f"{key} map {i}: {field} {ma[field]} (golden {mb[field]})")
            for field in ("matrix", "depth_row", "view_depth_range", "region"):
                if not _close(ma[field], mb[field]):
                    lines.append(f"{key} map {i}: {field} differs")
        for field in ("theta", "gamma", "n_opt", "lam"):
            if not _scalar_close(a[field], b[field]):
                lines.append(f"{key}: {field} {a[field]} (golden {b[field]})")
        if a["fallbacks"] != b["fallbacks"]:
            lines.append(f"{key}: fallbacks {a['fallbacks']} (golden {b['fallbacks']})")
    return lines


def load() -> dict:
    with gzip.open(GOLDEN, "rt") as f:
        return json.load(f)


def write(data: dict) -> None:
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    with gzip.GzipFile(GOLDEN, "wb", mtime=0) as f:
        f.write(text.encode())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.warp.golden", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--write", action="store_true", help="store the working tree's maps as the golden")
    args = ap.parse_args(argv)
    now = snapshot()
    if args.write:
        write(now)
        print(f"wrote {len(now)} setups to {GOLDEN.relative_to(ROOT)}")
        return 0
    lines = differences(now, load())
    for line in lines:
        print(line)
    print(f"{len(now)} setups, {len(lines)} differences")
    return 1 if lines else 0


if __name__ == "__main__":
    sys.exit(main())
