"""The unit-cube fit (Stamminger-Drettakis §4: "fit to the unit cube").

Given a projective transform T whose output has w > 0 on the points that matter,
fit_to_unit_cube returns A @ T, with A affine on NDC, so that those points land
in [-1, 1]^3 and fill it: x and y bound the map image, z bounds depth (nearest
the light at -1). The same fit serves every method.
"""
from __future__ import annotations

import numpy as np

from .geometry import transform_h
from .types import WarpError

NDC_PAD = 1e-7
"""Relative margin so points exactly on B's boundary stay inside after rounding."""


def ndc_bounds(transform, points) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of the divided coordinates of ``points`` under ``transform``."""
    h = transform_h(transform, points)
    w = h[:, 3]
    if not np.all(w > 0):
        raise WarpError("internal: a point of B is behind the projection (w <= 0)")
    ndc = h[:, :3] / w[:, None]
    return ndc.min(axis=0), ndc.max(axis=0)


def window_matrix(lo, hi) -> np.ndarray:
    """The affine NDC map taking the box [lo, hi] onto [-1, 1]^3."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    ext = np.maximum(hi - lo, 0.0)
    pad = NDC_PAD * np.maximum(ext, np.max(ext) * 1e-6) + 1e-300
    lo, hi = lo - pad, hi + pad
    a = np.eye(4)
    a[[0, 1, 2], [0, 1, 2]] = 2.0 / (hi - lo)
    a[:3, 3] = -(hi + lo) / (hi - lo)
    return a


def fit_to_unit_cube(transform, points) -> np.ndarray:
    """A @ transform with ``points`` filling NDC [-1, 1]^3."""
    lo, hi = ndc_bounds(transform, points)
    return window_matrix(lo, hi) @ np.asarray(transform, dtype=np.float64)
