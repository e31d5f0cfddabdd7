"""Rays against axis-aligned boxes: the one slab test :mod:`.visibility` and ``addon.measure.box_scene`` share.
Boxes are closed shells: a ray starting inside hits the inner wall."""
from __future__ import annotations

import numpy as np

from .culling import BoxIndex, Selection


def slab_intervals(origins, inverse_directions, lo, hi, hit_axis: bool = False, axis: int = -1):
    """Where rays (origins, 1 / directions) enter and leave boxes [lo, hi] (broadcast, coordinates along ``axis``), and
    with ``hit_axis`` the axis of the face ``first_hits`` meets (from inside, the one left by); a ray in a slab's plane
    is inside it. Axis by axis, not a reduction over a short axis (numpy is slow there)."""
    near, far = [], []
    for o, inv, a, b in zip(*(np.moveaxis(np.asarray(v), axis, 0) for v in (origins, inverse_directions, lo, hi))):
        with np.errstate(invalid="ignore"):
            t1, t2 = (a - o) * inv, (b - o) * inv
        near.append(np.minimum(t1, t2))
        far.append(np.maximum(t1, t2))
    enter, leave = np.fmax(np.fmax(near[0], near[1]), near[2]), np.fmin(np.fmin(far[0], far[1]), far[2])
    if not hit_axis:
        return enter, leave
    entered = np.where(near[0] == enter, 0, np.where(near[1] == enter, 1, 2))
    left = np.where(far[0] == leave, 0, np.where(far[1] == leave, 1, 2))
    return enter, leave, np.where(enter >= 0, entered, left)


def first_hits(enter, leave, t_max) -> np.ndarray:
    """The hit distance of each (ray, box) pair, inf where it misses in [0, t_max]."""
    t = np.where(enter >= 0, enter, leave)                  # from inside: the inner wall
    hit = (enter <= leave) & (leave >= 0) & (t <= t_max)
    return np.where(hit, t, np.inf)


CHUNK = 1 << 14
"""(ray, cluster) or (ray, box) pairs tested at once: temporaries stay small enough for the cache."""


def ray_index(origins, directions, t_max, index: BoxIndex, selection: Selection | None = None,
              may_meet: np.ndarray | bool = True, ranks_per_round: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of each ray with the boxes of a culling index within [0, t_max]: (t, box in the original order;
    inf and -1 for none), as ``addon.measure.box_scene.ray_boxes``; ``may_meet`` (rays, clusters): the pairs tested."""
    o = np.ascontiguousarray(np.asarray(origins, dtype=np.float64).reshape(-1, 3).T)
    with np.errstate(divide="ignore"):
        inv = np.ascontiguousarray((1.0 / np.asarray(directions, dtype=np.float64).reshape(-1, 3)).T)
    t_max = np.asarray(t_max, dtype=np.float64).reshape(-1)
    n = o.shape[1]
    best, which = np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
    k = index.c_box_bounds.shape[2]
    usable = (np.arange(index.c_bounds.shape[1] * k) < index.count).reshape(-1, k)   # the last cluster is padded
    if selection is not None:
        usable = usable & selection.by_cluster
    clusters = np.flatnonzero(usable.any(axis=1))
    # Each cluster's usable boxes as a run of slots (clusters in order), and their bounds (3, S).
    counts = usable[clusters].sum(axis=1)
    slots = (clusters[:, None] * k + np.arange(k))[usable[clusters]]
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    flat = index.c_box_bounds.reshape(6, -1)[:, slots]
    box_lo, box_hi = np.ascontiguousarray(flat[:3]), np.ascontiguousarray(-flat[3:])
    c_lo, c_hi = index.c_bounds[:3, clusters], -index.c_bounds[3:, clusters]         # (3, C)
    # The clusters each ray meets, with its entry distance, a chunk of (ray, cluster) pairs at a time.
    pair_rays, pair_clusters = np.nonzero(np.broadcast_to(may_meet, (n, len(usable)))[:, clusters])
    found = [(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))]
    for first in range(0, len(pair_rays), CHUNK):
        rr, cc = pair_rays[first:first + CHUNK], pair_clusters[first:first + CHUNK]
        enter, leave = slab_intervals(o.take(rr, 1), inv.take(rr, 1), c_lo.take(cc, 1), c_hi.take(cc, 1), axis=0)
        near = np.maximum(enter, 0.0)
        meet = (enter <= leave) & (leave >= 0) & (near <= t_max[rr])
        found.append((rr[meet], cc[meet], near[meet]))
    ray, slot, near = (np.concatenate(a) for a in zip(*found))
    if not len(ray):
        return best, which
    order = np.lexsort((near, ray))                          # by ray, nearest cluster first
    ray, slot, near = ray[order], slot[order], near[order]
    rank = np.arange(len(ray)) - np.searchsorted(ray, ray, side="left")
    for lowest in range(0, int(rank.max()) + 1, ranks_per_round):
        pick = (rank >= lowest) & (rank < lowest + ranks_per_round)
        pick[pick] &= near[pick] < best[ray[pick]]
        picked = np.flatnonzero(pick)
        # Every (ray, box) pair of the picked (ray, cluster) pairs, a chunk of pairs at a time.
        ends = np.cumsum(counts[slot[picked]])
        cut = 0
        while cut < len(picked):
            stop = max(int(np.searchsorted(ends, (ends[cut - 1] if cut else 0) + CHUNK, side="right")), cut + 1)
            r, c = ray[picked[cut:stop]], slot[picked[cut:stop]]
            cut = stop
            per = counts[c]
            pair_ray = np.repeat(r, per)
            box = np.repeat(starts[c] - np.cumsum(per) + per, per) + np.arange(per.sum())
            e, l = slab_intervals(o.take(pair_ray, 1), inv.take(pair_ray, 1), box_lo.take(box, 1), box_hi.take(box, 1),
                                  axis=0)
            t = first_hits(e, l, t_max[pair_ray])
            # The pairs come ray by ray (``ray`` is sorted): each ray's nearest over its run.
            run = np.flatnonzero(np.diff(pair_ray, prepend=-1))
            nearest = np.minimum.reduceat(t, run)
            rays = pair_ray[run]
            better = nearest < best[rays]
            best[rays[better]] = nearest[better]
            won = np.isfinite(t) & (t == best[pair_ray])
            which[pair_ray[won]] = index.perm[slots[box[won]]]
    return best, which
