"""Shortcuts in B's construction equal the general path: clipping a body to a
box only by the box facets it reaches beyond (``body._clip_to_box``) gives the
same boundary, vertex for vertex, as cutting by all six (``brep.clip``)."""
import numpy as np
import pytest

from addon.warp import brep
from addon.warp.body import _BOX_NORMALS_LIST, _box_offsets, _clip_to_box
from addon.warp.polyhedron import ConvexPolytope

TOL = 1e-10


def random_body(rng) -> brep.Brep:
    """A box cut by a few random planes through its inside (as R and the light hull are)."""
    b = ConvexPolytope.box([-1, -2, -1.5], [2, 1, 1.5], TOL).brep()
    for _ in range(rng.integers(0, 6)):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        cut = brep.cut(b, n.tolist(), float(rng.uniform(0.2, 1.0)), TOL)
        b = cut if cut is not None else b
    return b


@pytest.mark.parametrize("seed", range(40))
def test_clip_to_box_equals_the_six_cuts(seed):
    rng = np.random.default_rng(seed)
    b = random_body(rng)
    v = np.array(b.vertices)
    for _ in range(10):
        # Boxes from well inside the body to well around it, some facets exactly on its extent.
        lo = v.min(axis=0) + rng.uniform(-0.5, 1.0, 3) * rng.integers(0, 2, 3)
        hi = v.max(axis=0) - rng.uniform(-0.5, 1.0, 3) * rng.integers(0, 2, 3)
        box_o = _box_offsets([lo.tolist(), hi.tolist()], 0.0)
        try:
            expected = brep.clip(b, _BOX_NORMALS_LIST, box_o, TOL)
        except brep.OpenCut:
            with pytest.raises(brep.OpenCut):
                _clip_to_box(b, box_o, TOL)
            continue
        assert _clip_to_box(b, box_o, TOL) == expected
    beyond = _box_offsets([(v.max(axis=0) + 1).tolist(), (v.max(axis=0) + 2).tolist()], 0.0)
    assert _clip_to_box(b, beyond, TOL) is None and brep.clip(b, _BOX_NORMALS_LIST, beyond, TOL) is None
