"""Which of a scene's boxes meet a convex region (the receivers meeting V ∩ L, the casters meeting hull(R ∪ light),
every frame) and the box around them: exactly the plain per-box test, through a two-level index (:class:`BoxIndex`)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .types import SceneBounds


class Selection(NamedTuple):
    """The boxes of a ``BoxIndex`` that meet a convex region, in the index's order."""

    index: "BoxIndex"
    selected: np.ndarray
    """Which boxes meet the region, in the index's (cluster) order."""
    box: np.ndarray | None
    """The (2, 3) bounding box of those boxes, or None when there are none."""
    by_cluster: np.ndarray
    """``selected`` as (clusters, CLUSTER_SIZE), the last cluster padded with False."""

    @property
    def clusters(self) -> np.ndarray:
        """The clusters that hold a selected box, in order."""
        return np.flatnonzero(self.by_cluster.any(axis=1))

    @property
    def mask(self) -> np.ndarray:
        """Which of the indexed boxes (in their original order) meet the region."""
        mask = np.zeros(self.index.count, dtype=bool)
        mask[self.index.perm] = self.selected
        return mask

    @property
    def boxes(self) -> np.ndarray:
        """The (K, 2, 3) boxes that meet the region, in their original order."""
        return np.compress(self.mask, self.index.boxes, axis=0)


def _least_weights(normals: np.ndarray) -> np.ndarray:
    """(planes, 6): (n⁺, n⁻), n⁺ = max(n, 0), n⁻ = n⁺ - n, so a plane's least value
    over a box [lo, hi] is one product with the box's (lo, -hi)."""
    pos = np.maximum(normals, 0.0)
    return np.concatenate([pos, pos - normals], axis=1)


CLUSTER_SIZE = 32
"""Boxes per cluster of the two-level culling index."""


class BoxIndex:
    """Boxes in clusters of ``CLUSTER_SIZE`` (the leaves of a median-split k-d tree) with their bounds."""

    def __init__(self, boxes: np.ndarray):
        b = self.boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
        self.count = len(b)
        k = CLUSTER_SIZE
        n_c = -(-self.count // k)
        self.perm = self._clusters(b, k)
        # Each cluster's boxes, the last padded with copies of its last box: (6, clusters, k) lo and -hi.
        sb = b[np.concatenate([self.perm, np.repeat(self.perm[-1:], n_c * k - self.count)])]
        lo, hi = sb[:, 0].reshape(n_c, k, 3), sb[:, 1].reshape(n_c, k, 3)
        self.c_box_bounds = np.ascontiguousarray(np.concatenate([lo, -hi], axis=2).transpose(2, 0, 1))   # lo, -hi
        # The clusters' bounds, (6, clusters) lo and -hi (numpy reduces along a long last axis far faster
        # than over (N, 3) rows), and next to them (hi, -lo): see ``select``.
        self.c_bounds = self.c_box_bounds.min(axis=2)
        self.c_extremes = np.concatenate([self.c_bounds, -self.c_bounds[[3, 4, 5, 0, 1, 2]]], axis=1)

    @staticmethod
    def _clusters(b: np.ndarray, k: int) -> np.ndarray:
        """The boxes' order by cluster: leaves of a median-split k-d tree over their centres (all but the last full)."""
        centre = (b[:, 0] + b[:, 1]) / 2
        leaves: list[np.ndarray] = []
        todo = [np.arange(len(b))]
        while todo:
            ids = todo.pop()
            if len(ids) <= k:
                leaves.append(ids)
                continue
            ext = b[ids, 1].max(axis=0) - b[ids, 0].min(axis=0)
            axis = int(np.argmax(ext))
            half = (len(ids) // (2 * k)) * k or k      # left part: whole clusters
            part = np.argpartition(centre[ids, axis], half - 1)
            todo.append(ids[part[half:]])
            todo.append(ids[part[:half]])
        # Leaves come depth-first, left part first.
        return np.concatenate(leaves)

    @classmethod
    def of(cls, scene: SceneBounds, which: str) -> "BoxIndex":
        """The index of ``scene.casters`` or ``scene.receivers`` (built once per scene)."""
        def build():
            boxes = getattr(scene, which)
            other = scene.receivers if which == "casters" else scene.casters
            if other is boxes or (other.shape == boxes.shape and np.array_equal(other, boxes)):
                return scene.cached(("BoxIndex", "boxes"), lambda: cls(boxes))
            return cls(boxes)
        return scene.cached(("BoxIndex", which), build)

    def select(self, normals, offsets, tol: float = 0.0) -> Selection:
        """The boxes meeting ``normals @ x <= offsets`` (within ``tol``), by the clusters' bounds first."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(offsets, dtype=np.float64).reshape(-1)
        if self.count == 0:
            return Selection(self, np.zeros(0, dtype=bool), None, np.zeros((0, CLUSTER_SIZE), dtype=bool))
        k = CLUSTER_SIZE
        lowest = _least_weights(n)
        limit = o[:, None] + tol
        # (planes, 2 clusters): above the offset at the cluster's least, then at its greatest value.
        above = lowest @ self.c_extremes > limit
        clusters = above.shape[1] // 2
        c_out = above[:, :clusters].any(axis=0)              # wholly outside some half-space
        crossing = above[:, clusters:] & ~c_out              # not wholly inside this one
        c_edge = crossing.any(axis=0)
        c_in = ~(c_out | c_edge)                             # wholly inside every half-space
        selected = np.repeat(c_in, k).reshape(-1, k)
        least = self.c_bounds.compress(c_in, axis=1).min(axis=1, initial=np.inf)     # lo, then -hi
        edge = np.flatnonzero(c_edge)
        if len(edge):
            boxes = np.take(self.c_box_bounds, edge, axis=1).reshape(6, -1)          # (6, edge boxes)
            crossing = crossing[:, edge]
            planes = np.flatnonzero(crossing.any(axis=1))                           # (those crossing none: no test)
            box_limit = np.where(crossing[planes], limit[planes], np.inf)           # (planes, edge clusters)
            hit = ~((lowest[planes] @ boxes).reshape(len(planes), -1, k) > box_limit[:, :, None]).any(axis=0)
            selected[edge] = hit
            least = np.minimum(least, boxes.compress(hit.ravel(), axis=1).min(axis=1, initial=np.inf))
        selected[-1, self.count - (len(selected) - 1) * k:] = False          # the last cluster's padding
        flat = selected.ravel()[: self.count]
        return Selection(self, flat, np.array([least[:3], -least[3:]]) if flat.any() else None, selected)
