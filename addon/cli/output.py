"""The warp core's results as JSON data: what ``python -m addon.warp`` prints, the
export operator writes and the scripts save."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..warp.diagnostics import Diagnostics
from ..warp.types import ShadowMap, ShadowSetup


def setup_json(setup: ShadowSetup) -> dict:
    """``{"maps": [...], "diagnostics": {...}}``."""
    return {"maps": [map_json(m) for m in setup.maps], "diagnostics": diagnostics_json(setup.diagnostics)}


def map_json(m: ShadowMap) -> dict:
    """A map's matrix, size, depth test and role, and what else it carries."""
    out: dict[str, Any] = {"matrix": m.matrix.tolist(), "size": [int(m.size[0]), int(m.size[1])],
                           "depth_test": m.depth_test, "role": m.role}
    if m.view_depth_range is not None:
        out["view_depth_range"] = [float(v) for v in m.view_depth_range]
    if m.region is not None:
        r = m.region
        out["region"] = {"normal": r.normal.tolist(), "offset": float(r.offset),
                         "polygon": np.asarray(r.polygon).tolist(), "tolerance": float(r.tolerance)}
    if m.depth_row is not None:
        out["depth_row"] = np.asarray(m.depth_row).tolist()
    if m.blend_band > 0:
        out["blend_band"] = float(m.blend_band)
    return out


def diagnostics_json(d: Diagnostics) -> dict:
    """The diagnostics, angles in degrees, every value read."""
    out = {
        "method": d.method,
        "theta_deg": None if d.theta is None else math.degrees(d.theta),
        "gamma_deg": None if d.gamma is None else math.degrees(d.gamma),
        "n_opt": d.n_opt,
        "lambda": d.lam,
        "body_vertices": plain(d.body_vertices),
        "warp_frustum_corners": plain(d.warp_frustum_corners),
        "fallbacks": [{"what": w, "reason": r} for w, r in d.fallbacks],
    }
    out.update(plain(d.extra))
    return out


def plain(v):
    """``v`` as JSON data (arrays and numpy scalars as lists and numbers)."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v
