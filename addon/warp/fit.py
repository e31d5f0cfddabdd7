"""The unit-cube fit (Stamminger-Drettakis §4: "fit to the unit cube").

Given a projective transform T whose output has w > 0 on the points that matter,
fit_to_unit_cube returns A @ T, with A affine on NDC, so that those points land
in [-1, 1]^3 and fill it: x and y bound the map image, z bounds depth (nearest
the light at -1). The same fit serves every method.
"""
from __future__ import annotations

import numpy as np

from .geometry import transform_h, transform_h_runs
from .types import WarpError

NDC_PAD = 1e-7
"""Relative margin so points exactly on B's boundary stay inside after rounding."""


def ndc_bounds(transform, points) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of the divided coordinates of ``points`` under ``transform``."""
    return ndc_box(transform_h(transform, points))


def ndc_box(h) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of the divided coordinates of homogeneous points ``h`` (N, 4)."""
    w = h[:, 3:]
    if not (w > 0).all():
        raise WarpError("internal: a point of B is behind the projection (w <= 0)")
    ndc = h[:, :3] / w
    return ndc.min(axis=0), ndc.max(axis=0)


def window_matrix(lo, hi) -> np.ndarray:
    """The affine NDC map taking the box [lo, hi] onto [-1, 1]^3."""
    lo, hi = np.asarray(lo, dtype=np.float64).tolist(), np.asarray(hi, dtype=np.float64).tolist()
    return np.array(_window_entries(lo, hi)).reshape(4, 4)


def window_matrices(lo: list, hi: list) -> np.ndarray:
    """``window_matrix`` for several boxes given as lists of float 3-lists, (k, 4, 4)."""
    entries = []
    for a, b in zip(lo, hi):
        entries += _window_entries(a, b)
    return np.array(entries).reshape(-1, 4, 4)


def _window_entries(lo: list, hi: list) -> list:
    """``window_matrix`` for a box given as float lists: its 16 entries, row by row
    (a scale on the diagonal and an offset in the last column for each axis).
    Each axis is padded by ``NDC_PAD`` of its extent, or of a millionth of the
    box's largest extent if that is more (a flat box still gets a window)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    least = max(x1 - x0, y1 - y0, z1 - z0, 0.0) * 1e-6
    sx, ox = _axis_window(x0, x1, least)
    sy, oy = _axis_window(y0, y1, least)
    sz, oz = _axis_window(z0, z1, least)
    return [sx, 0.0, 0.0, ox, 0.0, sy, 0.0, oy, 0.0, 0.0, sz, oz, 0.0, 0.0, 0.0, 1.0]


def _axis_window(a: float, b: float, least: float) -> tuple[float, float]:
    """The scale and offset taking [a, b], padded, onto [-1, 1]."""
    pad = NDC_PAD * max(b - a, least) + 1e-300
    a, b = a - pad, b + pad
    return 2.0 / (b - a), -(b + a) / (b - a)


def fit_to_unit_cube(transform, points) -> np.ndarray:
    """A @ transform with ``points`` filling NDC [-1, 1]^3."""
    lo, hi = ndc_bounds(transform, points)
    return window_matrix(lo, hi) @ np.asarray(transform, dtype=np.float64)


def fit_keeping_points(transform, points) -> tuple[np.ndarray, np.ndarray]:
    """``fit_to_unit_cube`` and the ``points`` as the fitted map divides them
    (the window is a scale and an offset per axis of the divided coordinates)."""
    transform = np.asarray(transform, dtype=np.float64)
    h = np.asarray(points, dtype=np.float64) @ transform[:, :3].T + transform[:, 3]
    w = h[:, 3:]
    if not (w > 0).all():
        raise WarpError("internal: a point of B is behind the projection (w <= 0)")
    ndc = h[:, :3] / w
    window = window_matrix(ndc.min(axis=0), ndc.max(axis=0))
    return window @ transform, ndc * window.diagonal()[:3] + window[:3, 3]


def fit_runs(matrices, points_h, starts, run) -> np.ndarray:
    """``fit_to_unit_cube`` for several maps at once: map k (``matrices``,
    (k, 4, 4)) is fitted to its own run of the homogeneous points (N, 4), the
    rows from ``starts[k]`` to the next start (``geometry.point_runs``; ``run``
    names each row's map). Returns the fitted maps (k, 4, 4)."""
    h = transform_h_runs(matrices, points_h, run)
    w = h[:, 3:]
    if not (w > 0).all():
        raise WarpError("internal: a point of B is behind the projection (w <= 0)")
    ndc = h[:, :3] / w
    lo, hi = np.minimum.reduceat(ndc, starts).tolist(), np.maximum.reduceat(ndc, starts).tolist()
    return window_matrices(lo, hi) @ matrices
