"""brep.cut's walk for a plane through no vertex (crossings in the dropped
vertices' ids, kept loops shared, the cap from each walked facet's exit and
entry) gives the polyhedron the general walk (``_cut_through_vertices``) gives:
the same vertices up to rounding, the same facet planes and the same loops up to
renumbering, on random bodies cut by random planes, planes nearly parallel to a
facet and planes just off a vertex; planes through a vertex take the general
walk. Neither walk changes the body it cuts."""
import copy

import numpy as np

from addon.warp import brep
from addon.warp.polyhedron import ConvexPolytope

from test_brep import assert_closed_convex

TOL = 1e-10 * 6.0


def random_body(rng) -> brep.Brep:
    """A box cut by a few random planes through its middle."""
    b = ConvexPolytope.box(rng.uniform(-3.0, -0.5, 3), rng.uniform(0.5, 3.0, 3), TOL).brep()
    for _ in range(int(rng.integers(0, 8))):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        cut = brep.cut(b, n.tolist(), float(rng.uniform(0.1, 1.5)), TOL)
        if cut is not None:
            b = cut
    return b


def planes(rng, b: brep.Brep):
    """(normal, offset, through a vertex) to cut ``b`` by: random, nearly
    parallel to one of its facets, within a few tolerances of a vertex, and
    through a vertex."""
    v = np.array(b.vertices)
    for _ in range(4):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        h = v @ n
        yield n, float(rng.uniform(h.min(), h.max())), False
    f = int(rng.integers(len(b.normals)))
    for tilt in (1e-12, 1e-9, 1e-6, 1e-3):
        n = np.array(b.normals[f]) + tilt * rng.normal(size=3)
        n /= np.linalg.norm(n)
        h = v @ n
        yield n, float(b.offsets[f] - rng.uniform(0.0, 1.0) * tilt * np.ptp(h)), False
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    corner = v[int(rng.integers(len(v)))]
    for shift in (0.0, 0.5, 2.0, 10.0):
        yield n, float(n @ corner + shift * TOL * rng.choice([-1.0, 1.0])), shift < 1.0


def distances(b: brep.Brep, normal, offset: float) -> list:
    """The vertices' signed distances to the plane, as ``brep.cut`` computes them."""
    nx, ny, nz = normal
    return [nx * x + ny * y + nz * z - offset for x, y, z in b.vertices]


def same_polyhedron(a: brep.Brep, b: brep.Brep):
    """Equal vertices (up to rounding, in any order), facets and loops (up to renumbering and rotation)."""
    va, vb = np.array(a.vertices), np.array(b.vertices)
    assert va.shape == vb.shape
    gap = np.linalg.norm(va[:, None] - vb[None], axis=2)
    match = gap.argmin(axis=1)
    assert np.all(gap[np.arange(len(va)), match] <= 1e-12 * max(1.0, np.abs(vb).max()))
    assert sorted(match.tolist()) == list(range(len(vb)))
    assert list(a.normals) == list(b.normals) and list(a.offsets) == list(b.offsets)
    for la, lb in zip(a.loops, b.loops):
        mapped = [int(match[i]) for i in la]
        assert len(mapped) == len(lb)
        k = list(lb).index(mapped[0])
        assert mapped == list(lb[k:]) + list(lb[:k])


def test_the_cut_off_the_vertices_is_the_general_walk():
    rng = np.random.default_rng(20261122)
    checked = through = refused = 0
    for _ in range(300):
        b = random_body(rng)
        for n, o, on_vertex in planes(rng, b):
            before = copy.deepcopy(b)
            d = distances(b, n.tolist(), o)
            try:
                general = brep._cut_through_vertices(b, n.tolist(), o, TOL, d) \
                    if max(d) > TOL and min(d) < -TOL else brep.cut(b, n.tolist(), o, TOL)
            except brep.OpenCut:
                general = brep.OpenCut
            try:
                cut = brep.cut(b, n.tolist(), o, TOL)
            except brep.OpenCut:
                cut = brep.OpenCut
            assert b == before                     # neither walk changes its input
            if on_vertex or min(map(abs, d)) <= TOL:
                through += 1
                assert cut is general or cut == general
                continue
            if cut is brep.OpenCut:
                refused += 1
                continue
            assert general is not brep.OpenCut
            if cut is None or cut is b:
                assert general is cut
                continue
            checked += 1
            same_polyhedron(cut, general)
            assert_closed_convex(cut, tol=1e-8)
    assert checked > 2000 and through > 300 and refused == 0


def test_a_cut_dropping_more_vertices_than_it_makes_numbers_them_without_gaps():
    """A unit box cut down to its corner at the origin (x + y + z <= 0.5):
    seven vertices dropped, three crossings made; the tetrahedron's vertices
    are 0 .. 3, every one used, as the general walk gives them."""
    b = ConvexPolytope.box(np.zeros(3), np.ones(3), TOL).brep()
    n = (np.ones(3) / np.sqrt(3.0)).tolist()
    o = 0.5 / np.sqrt(3.0)
    cut = brep.cut(b, n, o, TOL)
    assert_closed_convex(cut)
    assert len(cut.vertices) == 4 and len(cut.loops) == 4
    same_polyhedron(cut, brep._cut_through_vertices(b, n, o, TOL, distances(b, n, o)))
