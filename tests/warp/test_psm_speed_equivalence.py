"""The fast paths of PSM's post-perspective pieces equal the plain general ones
on random configurations: Wolfe's nearest point with plain-float affine solves
against the same algorithm with numpy's bordered solves, and the nearest point
of a region inside boxes (edge clipping, the region's edges read from its facet
loops) against clipping the region by each box and taking the least vertex."""
from __future__ import annotations

import numpy as np
import pytest

from addon.warp.polyhedron import ConvexPolytope
from addon.warp.post_perspective import lowest_in_boxes, min_norm_point, smallest_cone


def _wolfe_reference(points, max_iter=200):
    """Wolfe's algorithm with the affine solves on numpy's bordered system."""
    p = np.asarray(points, dtype=np.float64)
    sq = np.einsum("ij,ij->i", p, p)
    scale = max(float(sq.max()), 1e-300)
    support = [int(np.argmin(sq))]
    weights = np.array([1.0])
    x = p[support[0]].copy()
    for _ in range(max_iter):
        dots = p @ x
        j = int(np.argmin(dots))
        if x @ x - dots[j] <= 1e-14 * scale or j in support:
            break
        support.append(j)
        weights = np.append(weights, 0.0)
        for _ in range(max_iter):
            q = p[support]
            n = len(support)
            a = np.ones((n + 1, n + 1))
            a[:n, :n] = q @ q.T
            a[n, n] = 0.0
            rhs = np.zeros(n + 1)
            rhs[n] = 1.0
            try:
                alpha = np.linalg.solve(a, rhs)[:n]
            except np.linalg.LinAlgError:
                alpha = np.linalg.lstsq(a, rhs, rcond=None)[0][:n]
            if np.all(alpha > 1e-15):
                weights, x = alpha, alpha @ q
                break
            neg = alpha <= 1e-15
            theta = float(np.min(weights[neg] / (weights[neg] - alpha[neg])))
            weights = theta * alpha + (1.0 - theta) * weights
            keep = weights > 1e-15
            support = [s for s, k in zip(support, keep) if k]
            weights = weights[keep] / weights[keep].sum()
            x = weights @ p[support]
    return x


def test_min_norm_point_equals_wolfe_with_numpy_solves():
    rng = np.random.default_rng(11)
    for t in range(3000):
        pts = rng.normal(size=(int(rng.integers(1, 30)), 3)) + rng.normal(size=3) * rng.uniform(0, 4)
        if t % 3 == 0:                       # unit directions, as smallest_cone gives it
            pts /= np.linalg.norm(pts, axis=1)[:, None]
        if t % 7 == 0:                       # coplanar points and repeated ones
            pts[:, 2] = 0.5
            pts = np.concatenate([pts, pts[:3]])
        if t % 11 == 0:                      # another dimension
            pts = pts[:, :2]
        expected = _wolfe_reference(pts)
        assert np.abs(min_norm_point(pts) - expected).max() <= 1e-12 * np.abs(pts).max()


def test_smallest_cone_of_a_light_far_outside_is_narrow():
    rng = np.random.default_rng(4)
    d = rng.normal(size=(25, 3)) * 0.05 + [0.0, 0.0, 1.0]
    d /= np.linalg.norm(d, axis=1)[:, None]
    k, margin = smallest_cone(d)
    assert np.all(d @ k >= margin - 1e-12) and margin > 0.9


@pytest.mark.parametrize("seed", range(4))
def test_lowest_in_boxes_equals_the_least_vertex_of_each_clipped_region(seed):
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(int(rng.integers(5, 14)), 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    region = ConvexPolytope.from_halfspaces(normals, rng.uniform(1.0, 3.0, len(normals)), 1e-9)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    centre = rng.uniform(-3, 3, size=(40, 3))
    half = rng.uniform(0.05, 2.5, size=(40, 3))
    lo, hi = centre - half, centre + half
    got = lowest_in_boxes(region, lo, hi, axis)
    eye = np.eye(3)
    met = 0
    for i in range(len(lo)):
        part = region.clip(np.concatenate([eye, -eye]), np.concatenate([hi[i], -lo[i]]))
        if part is None:                     # nothing with volume in common (at most a touch)
            assert got[i] >= float(np.where(axis > 0, lo[i], hi[i]) @ axis) - 1e-9
            continue
        met += 1
        assert got[i] == pytest.approx(float((part.vertices @ axis).min()), abs=1e-9)
    assert met >= 10
