"""B's polytope edges (``ConvexPolytope.edges``) are every pair of consecutive
vertices of a facet loop, lower index first and sorted: checked against that
definition written out plainly, on B's polytopes from face loops and on
enumerated ones."""
import numpy as np
import pytest

from addon.warp.polyhedron import ConvexPolytope


def plain_edges(poly: ConvexPolytope):
    keys = sorted({(min(loop[i - 1], loop[i]), max(loop[i - 1], loop[i]))
                   for loop in poly.facet_loops() for i in range(len(loop))})
    return np.array(keys, dtype=np.int64).reshape(-1, 2)


@pytest.mark.parametrize("seed", range(20))
def test_edges_are_the_facet_loops_consecutive_pairs(seed):
    rng = np.random.default_rng(seed)
    box = ConvexPolytope.box([-1, -2, -1.5], [2, 1, 1.5], 1e-10)
    n = rng.normal(size=(rng.integers(1, 7), 3))
    o = rng.uniform(0.2, 1.0, len(n)) * np.linalg.norm(n, axis=1)
    for poly in (box.clip(n, o), ConvexPolytope.from_halfspaces(np.concatenate([box.normals, n]),
                                                                np.concatenate([box.offsets, o]), 1e-10)):
        pairs = poly.edges()
        assert pairs.dtype == np.int64 and not pairs.flags.writeable
        assert np.array_equal(pairs, plain_edges(poly))
