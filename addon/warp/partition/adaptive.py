"""Split depths of least largest predicted error E_i, Lloyd's m at its largest over R_i's vertices, equalised
as E_i = k_i·w_i^p_i over log widths w_i (docs/papers.md, ``addon/warp/partition``)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..types import Light, ShadowSetup, View

ROUNDS = 5
"""Equalising rounds (one evaluation per split each)."""
MIN_WIDTH = 1e-3
"""No split narrower than this fraction of the range's log width."""
MIN_POWER, MAX_POWER = 0.6, 3.0
"""The range of a split's local power p_i."""


def max_error(view: View, light: Light, setup: ShadowSetup, region_world: np.ndarray) -> float:
    """Lloyd's perspective aliasing at its largest over a convex region's vertices, each in the map that serves it."""
    from ..aliasing import perspective_aliasing
    points = np.asarray(region_world, dtype=np.float64).reshape(-1, 3)
    served = setup.map_index(points, tol=1e-6)
    return max([float(np.nanmax(perspective_aliasing(view, light, m.matrix, m.size, points[served == i]),
                                 initial=0.0)) for i, m in enumerate(setup.maps) if (served == i).any()], default=0.0)


def objective(errors: np.ndarray, shared_budget: bool) -> float:
    """The worst split's error, or with a shared budget the equalised one."""
    return float(np.sqrt(np.mean(errors * errors))) if shared_budget else float(errors.max())


def minimax_splits(errors_at: Callable[[np.ndarray], list], splits: np.ndarray, errors: list,
                   shared_budget: bool = False) -> np.ndarray:
    """The depths (ends kept) after ``ROUNDS`` (few: a long search settles where a split's B jumps) equalising steps
    on ``errors_at(C_0..C_N)`` from ``splits`` with ``errors``, or those if the :func:`objective` did not fall."""
    c, e = start, start_e = np.asarray(splits, dtype=np.float64), np.asarray(errors, dtype=np.float64)
    power = np.ones(len(e))
    for _ in range(ROUNDS if len(c) > 2 and usable(e) else 0):
        moved = equalising_step(c, e, power, shared_budget)
        moved_e = np.array(errors_at(moved))
        if not usable(moved_e):           # a split with nothing visible: no slope
            break
        power = local_power(np.diff(np.log(c)), e, np.diff(np.log(moved)), moved_e, power)
        c, e = moved, moved_e
    return c if objective(e, shared_budget) < objective(start_e, shared_budget) else start


def usable(errors: np.ndarray) -> bool:
    """Every split's error finite and positive."""
    return bool(np.all(np.isfinite(errors)) and np.all(errors > 0))


def local_power(w0, e0, w1, e1, fallback) -> np.ndarray:
    """p_i of E_i = k_i·w_i^p_i through two measurements (``fallback`` where the width barely moved)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.log(e1 / e0) / np.log(w1 / w0)
    return np.clip(np.where(np.isfinite(p) & (np.abs(np.log(w1 / w0)) > 1e-3), p, fallback), MIN_POWER, MAX_POWER)


def equalising_step(c: np.ndarray, errors: np.ndarray, power: np.ndarray, shared_budget: bool) -> np.ndarray:
    """The depths whose log widths make the modelled errors equal (k w^p = t),
    or with a shared budget p k² w^(2p-1) = t, summing to ln(z_f/z_n)."""
    widths = np.diff(np.log(c))
    k, total = errors / widths ** power, widths.sum()
    a, q = (power * k * k, 2.0 * power - 1.0) if shared_budget else (k, power)     # the equalised a·w^q = t

    def width_at(t: float) -> np.ndarray:
        return (t / a) ** (1.0 / q)

    guess = np.log(a * widths ** q)
    lo, hi = guess.min() - 50.0, guess.max() + 50.0
    for _ in range(60):        # bisection in log t: the widths grow with t
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if width_at(np.exp(mid)).sum() < total else (lo, mid)
    target = np.maximum(width_at(np.exp(hi)), MIN_WIDTH * total)
    return c[0] * np.exp(np.concatenate([[0.0], np.cumsum(target * total / target.sum())]))
