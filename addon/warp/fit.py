"""The unit-cube fit (Stamminger-Drettakis §4): A @ T, A affine on NDC, so that the
points that matter (w > 0 under T) fill [-1, 1]^3, depth nearest the light at -1."""
from __future__ import annotations

import numpy as np

from .geometry import transform_h_runs
from .types import WarpError

NDC_PAD = 1e-7
"""Relative margin so points exactly on B's boundary stay inside after rounding."""


def divided(h) -> np.ndarray:
    """The divided coordinates (..., N, 3) of homogeneous points ``h`` (..., N, 4), all with w > 0."""
    w = h[..., 3:]
    if not (w > 0).all():
        raise WarpError("internal: a point of B is behind the projection (w <= 0)")
    return h[..., :3] / w


def window_matrix(lo, hi) -> np.ndarray:
    """The affine NDC map taking the box [lo, hi] onto [-1, 1]^3."""
    return window_matrices([np.asarray(lo, dtype=np.float64).tolist()], [np.asarray(hi, dtype=np.float64).tolist()])[0]


def window_matrices(lo: list, hi: list) -> np.ndarray:
    """``window_matrix`` for several boxes given as lists of float 3-lists, (k, 4, 4); each axis padded by
    ``NDC_PAD`` of its extent, or of a millionth of the box's largest extent if more (a flat box)."""
    entries = []
    for low, high in zip(lo, hi):
        least = max(*(b - a for a, b in zip(low, high)), 0.0) * 1e-6
        (sx, ox), (sy, oy), (sz, oz) = (_axis_window(a, b, least) for a, b in zip(low, high))
        entries += [sx, 0.0, 0.0, ox, 0.0, sy, 0.0, oy, 0.0, 0.0, sz, oz, 0.0, 0.0, 0.0, 1.0]
    return np.array(entries).reshape(-1, 4, 4)


def _axis_window(a: float, b: float, least: float) -> tuple[float, float]:
    """The scale and offset taking [a, b], padded, onto [-1, 1]."""
    pad = NDC_PAD * max(b - a, least) + 1e-300
    a, b = a - pad, b + pad
    return 2.0 / (b - a), -(b + a) / (b - a)


def fit_to_unit_cube(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """A @ ``transform`` (4, 4), or each of a stack (k, 4, 4), with the (N, 3) ``points`` filling NDC [-1, 1]^3."""
    ndc = divided(points @ np.swapaxes(transform[..., :3], -1, -2) + transform[..., None, :, 3])
    lo, hi = ndc.min(axis=-2).reshape(-1, 3).tolist(), ndc.max(axis=-2).reshape(-1, 3).tolist()
    return window_matrices(lo, hi).reshape(transform.shape) @ transform


def fit_runs(matrices, points_h, starts, run) -> np.ndarray:
    """``fit_to_unit_cube`` of maps (k, 4, 4), each to its run of the points (N, 4) (``geometry.point_runs``)."""
    ndc = divided(transform_h_runs(matrices, points_h, run))
    lo, hi = np.minimum.reduceat(ndc, starts).tolist(), np.maximum.reduceat(ndc, starts).tolist()
    return window_matrices(lo, hi) @ matrices
