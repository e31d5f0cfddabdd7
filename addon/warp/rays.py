"""Rays against axis-aligned boxes: the one slab test the warp core (the
visible region from the scene's boxes, :mod:`.visibility`) and the
independent judge (``addon.measure.box_scene``) share.

Boxes are closed shells (meshes are surfaces): a ray starting inside a box
hits its inner wall.
"""
from __future__ import annotations

import numpy as np

from .culling import BoxIndex, Selection


def slab_intervals(origins, inverse_directions, lo, hi, entering_axis: bool = False):
    """For rays given by origins and 1 / direction, against boxes [lo, hi]
    (arrays of 3-vectors that broadcast, e.g. (R, 1, 3) against (1, M, 3)):
    where each ray enters and leaves each box, and with ``entering_axis`` the
    axis of the slab it enters by. A ray in a slab's plane (0 · inf = NaN)
    counts as inside that slab: fmax / fmin skip the NaN."""
    with np.errstate(invalid="ignore"):
        t1 = (lo - origins) * inverse_directions
        t2 = (hi - origins) * inverse_directions
    near, far = np.minimum(t1, t2), np.maximum(t1, t2)
    # Per axis, not a reduction over the short last axis (numpy is slow there).
    x, y, z = near[..., 0], near[..., 1], near[..., 2]
    enter = np.fmax(np.fmax(x, y), z)
    leave = np.fmin(np.fmin(far[..., 0], far[..., 1]), far[..., 2])
    if not entering_axis:
        return enter, leave
    return enter, leave, np.where(x == enter, 0, np.where(y == enter, 1, 2))


def _inverse(directions) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 1.0 / np.asarray(directions, dtype=np.float64)


def _first_hits(enter, leave, t_max) -> np.ndarray:
    """The hit distance of each (ray, box) pair, inf where it misses in [0, t_max]."""
    t = np.where(enter >= 0, enter, leave)                  # from inside: the inner wall
    hit = (enter <= leave) & (leave >= 0) & (t <= t_max)
    return np.where(hit, t, np.inf)


def ray_boxes(origins, directions, t_max, boxes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of each ray with (M, 2, 3) boxes within [0, t_max]:
    (t, box index, hit-face normal); t = inf where nothing is hit. Every ray
    against every box: for a few boxes, or as the reference of :func:`ray_index`."""
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    rows = np.arange(len(origins))
    enter, leave, axes = slab_intervals(origins[:, None, :], _inverse(directions)[:, None, :],
                                        boxes[None, :, 0, :], boxes[None, :, 1, :], entering_axis=True)
    t = _first_hits(enter, leave, np.asarray(t_max, dtype=np.float64)[:, None])
    if t.shape[1] == 0:
        return np.full(len(origins), np.inf), np.zeros(len(origins), dtype=np.int64), np.zeros_like(origins)
    box = np.argmin(t, axis=1)
    tt = t[rows, box]
    axis = axes[rows, box]
    normal = np.zeros_like(origins)
    normal[rows, axis] = -np.sign(directions[rows, axis])
    return tt, box, normal


def ray_index(origins, directions, t_max, index: BoxIndex, selection: Selection | None = None,
              ranks_per_round: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of each ray with the boxes of a culling index (only those
    of ``selection``, if given) within [0, t_max]: (t, box index in the
    index's original order; inf and -1 where nothing is hit). Equals
    :func:`ray_boxes` on those boxes.

    The rays meet the index's clusters first; each ray then opens the clusters
    it meets nearest first, ``ranks_per_round`` at a time for all rays at
    once, and stops once its nearest hit is nearer than the next cluster's
    entry, so a scene of thousands of boxes costs about what the few clusters
    in front of each ray hold."""
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    inv = _inverse(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    t_max = np.asarray(t_max, dtype=np.float64).reshape(-1)
    n = len(origins)
    best, which = np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
    k = index.c_box_bounds.shape[2]
    usable = (np.arange(index.c_bounds.shape[1] * k) < index.count).reshape(-1, k)   # the last cluster is padded
    if selection is not None:
        usable = usable & selection.by_cluster
    clusters = np.flatnonzero(usable.any(axis=1))
    if n == 0 or not len(clusters):
        return best, which
    # Each cluster's usable boxes as a run of slots (clusters in order), and their bounds.
    counts = usable[clusters].sum(axis=1)
    slots = (clusters[:, None] * k + np.arange(k))[usable[clusters]]
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    flat = index.c_box_bounds.reshape(6, -1)[:, slots]
    box_lo, box_hi = flat[:3].T, -flat[3:].T                                        # (S, 3)
    c_lo, c_hi = index.c_bounds[:3, clusters].T, -index.c_bounds[3:, clusters].T      # (C, 3)
    enter, leave = slab_intervals(origins[:, None, :], inv[:, None, :], c_lo[None], c_hi[None])
    near = np.maximum(enter, 0.0)
    ray, slot = np.nonzero((enter <= leave) & (leave >= 0) & (near <= t_max[:, None]))
    if not len(ray):
        return best, which
    near = near[ray, slot]
    order = np.lexsort((near, ray))                          # by ray, nearest cluster first
    ray, slot, near = ray[order], slot[order], near[order]
    rank = np.arange(len(ray)) - np.searchsorted(ray, ray, side="left")
    for lowest in range(0, int(rank.max()) + 1, ranks_per_round):
        pick = (rank >= lowest) & (rank < lowest + ranks_per_round)
        pick[pick] &= near[pick] < best[ray[pick]]
        if not pick.any():
            continue
        r, c = ray[pick], slot[pick]
        # Every (ray, box) pair of the picked (ray, cluster) pairs.
        per = counts[c]
        pair_ray = np.repeat(r, per)
        box = np.repeat(starts[c] - np.cumsum(per) + per, per) + np.arange(per.sum())
        e, l = slab_intervals(origins[pair_ray], inv[pair_ray], box_lo[box], box_hi[box])
        t = _first_hits(e, l, t_max[pair_ray])
        # The pairs come ray by ray (``ray`` is sorted): each ray's nearest over its run.
        run = np.flatnonzero(np.diff(pair_ray, prepend=-1))
        nearest = np.minimum.reduceat(t, run)
        rays = pair_ray[run]
        better = nearest < best[rays]
        best[rays[better]] = nearest[better]
        won = np.isfinite(t) & (t == best[pair_ray])
        which[pair_ray[won]] = index.perm[slots[box[won]]]
    which[~np.isfinite(best)] = -1
    return best, which
