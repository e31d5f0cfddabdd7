"""The culling index (``culling.BoxIndex.select``) keeps exactly the boxes
not wholly outside one of the half-spaces (a box is outside a half-space when
its corner least along the normal is beyond the offset), with their bounding
box, also for boxes touching a plane exactly, no planes at all, a last cluster
that is not full and a region that meets no box."""
import numpy as np
import pytest

from addon.warp.culling import CLUSTER_SIZE, BoxIndex
from addon.warp.polyhedron import box_corners


def meeting(boxes: np.ndarray, n, o, tol: float) -> np.ndarray:
    """Box by box: no half-space has all eight corners beyond it."""
    least = (box_corners(boxes[:, 0], boxes[:, 1]) @ np.asarray(n).T).min(axis=1)      # (boxes, planes)
    return ~(least > np.asarray(o) + tol).any(axis=1)


def random_boxes(rng, count: int) -> np.ndarray:
    c = rng.uniform(-100, 100, (count, 3))
    h = rng.uniform(0.01, 5, (count, 3))
    boxes = np.stack([c - h, c + h], axis=1)
    if count > 3:
        boxes[count // 2] = [[-300, -300, -1], [300, 300, 0]]      # a ground slab, in every cluster's way
    return np.round(boxes, 2)          # short binary fractions: faces exactly on the axis-aligned planes below


def assert_selects_like_the_plain_test(index: BoxIndex, boxes: np.ndarray, n, o, tol: float):
    sel = index.select(n, o, tol)
    ref = meeting(boxes, n, o, tol)
    assert np.array_equal(sel.mask, ref)
    # per cluster: the same boxes, the last cluster's padding never selected
    assert np.array_equal(sel.by_cluster.ravel()[: index.count], sel.selected)
    assert not sel.by_cluster.ravel()[index.count:].any()
    assert np.array_equal(sel.clusters, np.unique(np.flatnonzero(sel.selected) // CLUSTER_SIZE))
    if ref.any():
        assert np.array_equal(sel.box, [boxes[ref, 0].min(axis=0), boxes[ref, 1].max(axis=0)])
    else:
        assert sel.box is None


@pytest.mark.parametrize("count", [1, 31, 32, 33, 500, 2017])
def test_select_equals_the_plain_test(count):
    rng = np.random.default_rng(count)
    boxes = random_boxes(rng, count)
    index = BoxIndex(boxes)
    for _ in range(60):
        n = rng.normal(size=(rng.integers(1, 20), 3))
        n /= np.linalg.norm(n, axis=1)[:, None]
        o = rng.normal(size=len(n)) * 60
        assert_selects_like_the_plain_test(index, boxes, n, o, float(rng.choice([0.0, 1e-9])))


def test_boxes_touching_an_axis_plane_are_kept():
    rng = np.random.default_rng(7)
    boxes = random_boxes(rng, 700)
    index = BoxIndex(boxes)
    for axis in range(3):
        for box in boxes[::37]:
            for sign, face in ((1.0, box[0]), (-1.0, -box[1])):
                n = np.zeros((1, 3))
                n[0, axis] = sign
                o = np.array([face[axis]])          # the plane through that face: the box touches the region
                assert_selects_like_the_plain_test(index, boxes, n, o, 0.0)
                assert index.select(n, o, 0.0).mask[np.flatnonzero((boxes == box).all(axis=(1, 2)))].all()


def test_no_planes_select_everything_and_an_empty_region_nothing():
    rng = np.random.default_rng(11)
    boxes = random_boxes(rng, 300)
    index = BoxIndex(boxes)
    sel = index.select(np.zeros((0, 3)), np.zeros(0))
    assert sel.mask.all()
    assert np.array_equal(sel.box, [boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])
    far = index.select([[0.0, 0.0, -1.0]], [-1000.0])        # z >= 1000: above every box
    assert not far.mask.any() and far.box is None
