"""Which of a scene's boxes meet a convex region, and the box around them.

B is cut down to what the view needs (body.py): the receivers that meet V ∩ L
and the casters that meet hull(R ∪ light), on scenes of thousands of boxes,
every frame. ``BoxIndex`` (built once per scene) groups the boxes in clusters
of ``CLUSTER_SIZE`` with their bounds: a cluster wholly outside a half-space
is rejected, one wholly inside all of them is accepted, and only the boxes of
the rest are tested, each against the planes that cross its cluster. The
result equals the plain per-box test (``boxes_meeting_arrays``).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .polyhedron import Plane
from .types import SceneBounds


class Selection(NamedTuple):
    """The boxes of a ``BoxIndex`` that meet a convex region, kept in the
    index's own order; the mask over the scene's boxes is made on demand."""

    index: "BoxIndex"
    selected: np.ndarray
    """Which boxes meet the region, in the index's (cluster) order."""
    box: np.ndarray | None
    """The (2, 3) bounding box of those boxes, or None when there are none."""

    @property
    def mask(self) -> np.ndarray:
        """Which of the indexed boxes (in their original order) meet the region."""
        mask = np.zeros(self.index.count, dtype=bool)
        mask[self.index.perm] = self.selected
        return mask


def _stack_of(boxes: np.ndarray) -> np.ndarray:
    """(6, N): rows 0-2 the boxes' centres, rows 3-5 their half extents."""
    return np.ascontiguousarray(np.concatenate([(boxes[:, 0] + boxes[:, 1]).T / 2, (boxes[:, 1] - boxes[:, 0]).T / 2]))


def boxes_meeting_arrays(normals, offsets, centre_half: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Boolean mask of boxes, given as (6, N) centres/half extents, not entirely
    outside any half-space ``normals @ x <= offsets`` (a conservative test)."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    count = centre_half.shape[1]
    if count == 0:
        return np.zeros(0, dtype=bool)
    if len(n) == 0:
        return np.ones(count, dtype=bool)
    m = np.concatenate([n, -np.abs(n)], axis=1)
    # (A non-contiguous operand makes matmul fall off BLAS and take 100x longer.)
    nearest = m @ np.ascontiguousarray(centre_half) - np.asarray(offsets, dtype=np.float64)[:, None]
    return nearest.max(axis=0) <= tol


CLUSTER_SIZE = 32
"""Boxes per cluster of the two-level culling index."""


class BoxIndex:
    """A two-level index over a scene's boxes for culling against convex
    regions: boxes grouped in clusters of ``CLUSTER_SIZE`` (the leaves of a
    median-split k-d tree) with their bounding boxes. A cluster wholly
    outside a half-space is rejected, one wholly inside all is accepted, and
    only the boxes of the remaining clusters are tested one by one. The result
    equals the plain per-box test (``boxes_meeting_arrays``)."""

    def __init__(self, boxes: np.ndarray):
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
        self.count = len(b)
        k = CLUSTER_SIZE
        n_c = -(-self.count // k)
        if self.count == 0:
            self.perm = np.zeros(0, dtype=np.int64)
            b = np.zeros((1, 2, 3))
        else:
            self.perm = self._clusters(b, k)
        # Each cluster's boxes, the last padded with copies of its last box: (6, clusters, k) lo and -hi, ...
        sb = b[np.concatenate([self.perm, np.repeat(self.perm[-1:], n_c * k - self.count)])] if self.count else b[:0]
        lo, hi = sb[:, 0].reshape(n_c, k, 3), sb[:, 1].reshape(n_c, k, 3)
        self.c_box_bounds = np.ascontiguousarray(np.concatenate([lo, -hi], axis=2).transpose(2, 0, 1))   # lo, -hi
        # ... and (clusters, 6, k) centres and half extents.
        self.c_boxes = np.ascontiguousarray(_stack_of(sb).reshape(6, n_c, k).transpose(1, 0, 2))
        # The clusters' bounds, (6, clusters) lo and -hi, and (6, clusters) centres and half extents
        # (numpy reduces along a long last axis far faster than over (N, 3) rows).
        self.c_bounds = self.c_box_bounds.min(axis=2)       # (6, clusters): lo, -hi
        self.c_stack = _stack_of(np.stack([self.c_bounds[:3].T, -self.c_bounds[3:].T], axis=1))

    @staticmethod
    def _clusters(b: np.ndarray, k: int) -> np.ndarray:
        """The boxes' order by cluster: leaves of a median-split k-d tree over
        the box centres (split along the widest axis of the boxes' extent), so
        each cluster is compact. Every leaf but the last is full."""
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

    def cull(self, normals, offsets, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray | None]:
        """(mask over the boxes in their original order, the (2, 3) bounding box
        of the boxes that meet the region or None)."""
        sel = self.select(normals, offsets, tol)
        return sel.mask, sel.box

    def select(self, normals, offsets, tol: float = 0.0) -> Selection:
        """The boxes that meet the region ``normals @ x <= offsets``. A box is
        tested only against the planes that cross its cluster: a cluster wholly
        inside a half-space has every box inside it."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(offsets, dtype=np.float64).reshape(-1)
        if self.count == 0:
            return Selection(self, np.zeros(0, dtype=bool), None)
        # A plane's least and greatest value over a box: n . centre -/+ |n| . half extent.
        an = np.abs(n)
        w = np.concatenate([np.concatenate([n, -an], axis=1), np.concatenate([n, an], axis=1)])
        bounds = w @ self.c_stack - np.concatenate([o, o])[:, None]       # (2 planes, clusters)
        c_out = (bounds[: len(n)] > tol).any(axis=0)          # wholly outside some half-space
        crossing = (bounds[len(n):] > tol) & ~c_out           # not wholly inside this one
        c_in = ~(c_out | crossing.any(axis=0))                # wholly inside every half-space
        selected = np.repeat(c_in, CLUSTER_SIZE).reshape(-1, CLUSTER_SIZE)
        bounds = self.c_bounds[:, c_in]                      # (6, clusters inside): lo, then -hi
        cluster, plane = np.nonzero(crossing.T)               # (cluster, plane) pairs, by cluster
        if len(cluster):
            first = np.flatnonzero(np.concatenate([[True], cluster[1:] != cluster[:-1]]))
            edge = cluster[first]
            least = np.matmul(w[plane, None, :], self.c_boxes[cluster])[:, 0] - o[plane, None]
            hit = ~np.logical_or.reduceat(least > tol, first, axis=0)        # (edge clusters, CLUSTER_SIZE)
            selected[edge] = hit
            bounds = np.concatenate([bounds, np.where(hit, self.c_box_bounds[:, edge], np.inf).reshape(6, -1)], axis=1)
        selected = selected.ravel()[: self.count]
        if not selected.any():
            return Selection(self, selected, None)
        least = bounds.min(axis=1)
        return Selection(self, selected, np.array([least[:3], -least[3:]]))


def boxes_meeting(planes: list[Plane], boxes: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Boolean mask of (N, 2, 3) boxes not entirely outside any half-space (a
    conservative box/convex-body overlap test)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    if not planes:
        return np.ones(len(b), dtype=bool)
    n = np.array([p.normal for p in planes])
    o = np.array([p.offset for p in planes])
    return boxes_meeting_arrays(n, o, _stack_of(b), tol)
