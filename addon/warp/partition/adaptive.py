"""Split positions that minimise the largest predicted error (Lloyd's model).

**The predicted error of a split** is Lloyd's perspective aliasing factor
m(p) (``aliasing.perspective_aliasing``) at its maximum over the split's
part of the view, R_i = V_i ∩ S_r ∩ L, for the maps the split's warp gives
it. For a sun m² = K·w³/(c·z²) is convex (``aliasing``, part 3), so the
maximum over the convex R_i is at one of its vertices and :func:`max_error`
is exact; for point and spot lights the vertices are a close estimate.

**The minimax split.** A cascade's error is its worst split's. With errors
E_i(C_i, C_(i+1)) that grow with a split's width, the optimum makes every E_i
equal. :func:`minimax_splits` equalises them in log depth, where the widths
w_i = ln(C_(i+1)/C_i) sum to ln(z_f/z_n), with a local model of each split's
error, E_i = k_i·w_i^p_i: k_i through its last error, p_i through its last
two (1 at first), and the widths that make every modelled error equal,

    k_i·w_i^p_i = E*,   Σ w_i = ln(z_f/z_n),

for a few rounds (a secant method on every split at once). It starts from the practical (PSSM λ)
splits and keeps them unless the rounds lowered the largest error, so its
largest predicted error is never above the λ splits' (``tests/warp/test_cascade.py``
checks the claim).

A shared texel budget (``budget``) asks for the least *equalised* error
instead: with texels shared in proportion to E_i², every split ends at
sqrt(Σ E_i² / n) of the per-map error, so the splits minimise Σ E_i², which
with E_i = k_i·w_i means w_i ∝ 1 / k_i².
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..types import ShadowSetup, View, Light

ROUNDS = 5
"""Fixed-point rounds of :func:`minimax_splits` (each costs one evaluation per split)."""
MIN_WIDTH = 1e-3
"""No split is narrower than this fraction of the range's log width."""
MIN_POWER, MAX_POWER = 0.6, 3.0
"""The range the local power law E_i ∝ w_i^p of a split's error may take
(from splits whose error barely moves with their width, to steep ones)."""


def max_error(view: View, light: Light, setup: ShadowSetup, region_world: np.ndarray) -> float:
    """Lloyd's perspective aliasing at its maximum over a convex region of the
    view given by its vertices, each measured in the map that serves it."""
    from ..aliasing import perspective_aliasing
    points = np.asarray(region_world, dtype=np.float64).reshape(-1, 3)
    served = setup.map_index(points, tol=1e-6)
    worst = 0.0
    for i, m in enumerate(setup.maps):
        mine = served == i
        if mine.any():
            worst = max(worst, float(np.nanmax(perspective_aliasing(view, light, m.matrix, m.size, points[mine]),
                                               initial=0.0)))
    return worst


def objective(errors: list[float], shared_budget: bool) -> float:
    """The cascade's predicted error: its worst split's with a map per split,
    or, with a shared budget, the error every split reaches when the texels
    go where they are needed (``budget.shared_sizes``)."""
    e = np.asarray(errors, dtype=np.float64)
    return float(np.sqrt(np.mean(e * e))) if shared_budget else float(e.max())


def minimax_splits(error_of: Callable[[int, float, float], float], splits: np.ndarray, errors: list,
                   shared_budget: bool = False) -> tuple[np.ndarray, list[float]]:
    """The split depths (first and last kept) after ``ROUNDS`` equalising
    steps on the predicted errors ``error_of(i, C_i, C_(i+1))``, from the
    start ``splits`` whose ``errors`` are given; the start itself when the
    steps did not lower the :func:`objective`. A few rounds and one
    comparison keep the result continuous in the configuration: a long
    search converges onto the depths where a split's B jumps (a receiver box
    entering it), and then tips either way under the slightest move."""
    start, start_e = np.asarray(splits, dtype=np.float64), np.asarray(errors, dtype=np.float64)
    c, e = start, start_e
    power = np.ones(len(e))
    for _ in range(ROUNDS if len(c) > 2 and usable(e) else 0):
        moved = equalising_step(c, e, power, shared_budget)
        moved_e = np.array([error_of(i, a, b) for i, (a, b) in enumerate(zip(moved[:-1], moved[1:]))])
        if not usable(moved_e):           # a split left with nothing visible: the model has no slope there
            break
        power = local_power(np.diff(np.log(c)), e, np.diff(np.log(moved)), moved_e, power)
        c, e = moved, moved_e
    if objective(e, shared_budget) < objective(start_e, shared_budget):
        return c, [float(x) for x in e]
    return start, [float(x) for x in start_e]


def usable(errors: np.ndarray) -> bool:
    """Whether every split has a finite, positive predicted error (holds something visible)."""
    return bool(np.all(np.isfinite(errors)) and np.all(errors > 0))


def local_power(w0, e0, w1, e1, fallback) -> np.ndarray:
    """p_i of E_i = k_i·w_i^p_i through two measurements of each split (its
    fallback where the width barely moved or an error is not positive)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.log(e1 / e0) / np.log(w1 / w0)
    usable = np.isfinite(p) & (np.abs(np.log(w1 / w0)) > 1e-3)
    return np.clip(np.where(usable, p, fallback), MIN_POWER, MAX_POWER)


def equalising_step(c: np.ndarray, errors: np.ndarray, power: np.ndarray, shared_budget: bool) -> np.ndarray:
    """The log widths w_i that the model E_i = k_i·w_i^p_i (k_i through the
    current errors) says are best, summing to ln(z_f / z_n): equal errors for
    a map per split, p_i·E_i²/w_i equal (Σ E_i² least) for a shared budget."""
    widths = np.diff(np.log(c))
    k = errors / widths ** power
    total = widths.sum()
    if shared_budget:          # p k² w^(2p - 1) = t
        width_at = lambda t: (t / (power * k * k)) ** (1.0 / (2.0 * power - 1.0))    # noqa: E731
    else:                      # k w^p = t
        width_at = lambda t: (t / k) ** (1.0 / power)                                # noqa: E731
    guess = np.log(k * widths ** power) if not shared_budget else np.log(power * k * k * widths ** (2 * power - 1))
    lo, hi = guess.min() - 50.0, guess.max() + 50.0          # (e^50: far beyond any width's reach)
    for _ in range(60):        # bisection in log t: the widths grow with t
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if width_at(np.exp(mid)).sum() < total else (lo, mid)
    target = np.maximum(width_at(np.exp(hi)), MIN_WIDTH * total)
    return c[0] * np.exp(np.concatenate([[0.0], np.cumsum(target * total / target.sum())]))
