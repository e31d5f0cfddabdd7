"""Convex polyhedra as face loops (``addon.warp.brep``) and the light hull built
on them (``body.light_hull``): a cut leaves a closed polyhedron with outward
counter-clockwise faces on their own planes, holding exactly the points of the
half-space, and hull(P ∪ light) holds P and the light and nothing beyond the
planes through its silhouette."""
import math

import numpy as np
import pytest

from addon.warp import brep
from addon.warp.light_hull import light_hull
from addon.warp.geometry import UNIT_CUBE_CORNERS
from addon.warp.polyhedron import ConvexPolytope

from test_body import AWKWARD_SAMPLES, BOX_HI, BOX_LO, awkward_cuts

TOL = 1e-10 * 6.0


def newell(points: np.ndarray) -> np.ndarray:
    """Newell's normal of a polygon: outward for a counter-clockwise loop seen from outside."""
    n = np.zeros(3)
    for a, b in zip(points, np.roll(points, -1, axis=0)):
        n += [(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])]
    return n


def assert_closed_convex(b: brep.Brep, tol: float = 1e-9):
    """Every directed edge has its reverse in another face (closed, consistently
    oriented), Euler V - E + F = 2, every vertex is used, each loop lies on its
    facet's plane and turns counter-clockwise about its outward normal, and every
    vertex is inside every facet's half-space."""
    v = np.array(b.vertices)
    owner = brep.directed_edges(b.loops)
    assert len(owner) == sum(len(loop) for loop in b.loops), "an edge appears twice in one direction"
    for (p, q), f in owner.items():
        assert (q, p) in owner and owner[(q, p)] != f, "open edge"
    assert len(v) - len(owner) // 2 + len(b.loops) == 2
    assert sorted({i for loop in b.loops for i in loop}) == list(range(len(v)))
    n, o = np.array(b.normals), np.array(b.offsets)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    for ni, oi, loop in zip(n, o, b.loops):
        assert len(loop) >= 3
        assert np.all(np.abs(v[loop] @ ni - oi) <= tol)
        area = newell(v[loop])
        assert area @ ni >= -tol * np.linalg.norm(area)
    assert np.all(v @ n.T - o <= tol)


def box_brep() -> brep.Brep:
    return ConvexPolytope.box(BOX_LO, BOX_HI, TOL).brep()


def test_a_box_and_a_frustum_have_outward_counter_clockwise_faces():
    assert_closed_convex(box_brep())
    projection = np.array([[1.2, 0, 0, 0], [0, 2.0, 0, 0], [0, 0, -1.02, -0.2], [0, 0, -1, 0]])
    h = np.c_[UNIT_CUBE_CORNERS, np.ones(8)] @ np.linalg.inv(projection).T
    assert_closed_convex(brep.hexahedron(h[:, :3] / h[:, 3:]))


def test_hexahedron_is_the_frustum_polytope():
    """Same planes as ConvexPolytope.from_corners, also for a mirrored (left-handed) corner order."""
    corners = np.array(UNIT_CUBE_CORNERS, dtype=float) * [2.0, 1.0, 0.5] + [1.0, -3.0, 2.0]
    for c in (corners, corners * [-1.0, 1.0, 1.0]):
        b = brep.hexahedron(c)
        p = ConvexPolytope.from_corners(c, TOL)
        assert_closed_convex(b)
        for n, o in zip(b.normals, b.offsets):
            assert np.any(np.all(np.isclose(p.normals, n), axis=1) & np.isclose(p.offsets, o))


def test_a_cut_holds_exactly_the_points_of_the_half_space():
    rng = np.random.default_rng(11)
    pts = rng.uniform(BOX_LO, BOX_HI, (3000, 3))
    for _ in range(200):
        b = box_brep()
        inside = np.ones(len(pts), dtype=bool)
        for _ in range(int(rng.integers(1, 7))):
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
            o = float(rng.uniform(-0.5, 2.0))
            cut = brep.cut(b, n.tolist(), o, TOL)
            inside &= pts @ n <= o
            if cut is None:
                assert not inside.any()
                break
            b = cut
        else:
            assert_closed_convex(b)
            poly = ConvexPolytope.from_brep(b, TOL)
            clear = np.abs(pts @ np.array(b.normals).T - np.array(b.offsets)).min(axis=1) > 1e-9
            assert np.array_equal(poly.contains(pts[clear], 0.0), inside[clear])


def test_a_cut_that_misses_returns_the_polyhedron_and_one_beyond_it_nothing():
    b = box_brep()
    assert brep.cut(b, [1.0, 0.0, 0.0], BOX_HI[0] + 1.0, TOL) is b
    assert brep.cut(b, [1.0, 0.0, 0.0], BOX_HI[0], TOL) is b                 # along a face
    assert brep.cut(b, [1.0, 0.0, 0.0], BOX_LO[0], TOL) is None              # leaves only a face
    assert brep.cut(b, [-1.0, 0.0, 0.0], -BOX_HI[0] - 1.0, TOL) is None


def test_a_cut_through_vertices_and_edges_shares_them():
    """A plane through two opposite edges of the box halves it: no new vertex,
    the four on the plane shared by both halves' caps."""
    b = box_brep()
    n = np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0)                      # through (lo_x, lo_y) and (hi_x, hi_y)
    d = BOX_HI - BOX_LO
    n = np.array([d[1], -d[0], 0.0]) / math.hypot(d[0], d[1])
    o = float(n @ BOX_LO)
    half = brep.cut(b, n.tolist(), o, TOL)
    assert_closed_convex(half)
    assert len(half.vertices) == 6 and len(half.loops) == 5


def test_awkward_cuts_close_or_fall_back_to_enumeration():
    """On the seeded degenerate cuts of test_body, the face walk either gives a
    closed polyhedron or says it cannot (OpenCut), never a wrong one; and it
    can on nearly all of them."""
    rng = np.random.default_rng(20261122)
    open_cuts = 0
    for _ in range(AWKWARD_SAMPLES):
        n, o = awkward_cuts(rng)
        unit = n / np.linalg.norm(n, axis=1, keepdims=True)
        offset = o / np.linalg.norm(n, axis=1)
        try:
            b = brep.clip(box_brep(), unit.tolist(), offset.tolist(), TOL)
        except brep.OpenCut:
            open_cuts += 1
            continue
        if b is not None:
            assert_closed_convex(b, tol=1e-8)
    assert open_cuts <= AWKWARD_SAMPLES // 100


# ----------------------------------------------------------------------------- the light hull

def hull_case(light_h):
    rng = np.random.default_rng(4)
    p = ConvexPolytope.box([-1.0, -2.0, -3.0], [2.0, 1.0, 3.0], TOL)
    for _ in range(3):
        n = rng.normal(size=(1, 3))
        p = p.clip(n, [0.8 * np.linalg.norm(n)])
    return p.brep(), light_h


LIGHTS = {
    "point outside": np.array([7.0, 5.0, 9.0, 1.0]),
    "point beside": np.array([-9.0, 0.3, 0.2, 1.0]),
    "sun": np.append(np.array([0.3, -0.4, 0.8]) / np.linalg.norm([0.3, -0.4, 0.8]), 0.0),
    "sun along an axis": np.array([0.0, 0.0, 1.0, 0.0]),
}


@pytest.mark.parametrize("name", LIGHTS)
def test_the_light_hull_holds_the_body_and_its_light_rays(name):
    b, light_h = hull_case(LIGHTS[name])
    hull = light_hull(b, light_h, TOL)
    v = np.array(b.vertices)
    # Every half-space holds P, and each side passes through the light.
    assert np.all(v @ hull.normals.T - hull.offsets <= 1e-12)
    sides = hull.normals[len(hull.kept):]
    if light_h[3]:
        p = light_h[:3] / light_h[3]
        assert np.allclose(sides @ p, hull.offsets[len(hull.kept):])
        assert np.all(hull.normals @ p - hull.offsets <= 1e-12)
    else:
        assert np.allclose(sides @ light_h[:3], 0.0)
    # Points of P moved towards the light stay inside.
    t = np.linspace(0.0, 1.0, 7)[:, None, None]
    target = light_h[:3] / light_h[3] if light_h[3] else v + 50.0 * light_h[:3]
    along = (v + t * (target - v)).reshape(-1, 3)
    assert np.all(along @ hull.normals.T - hull.offsets <= 1e-9)
    # Its boundary is closed, with P's vertices (those not hidden from the light) and the light or the cap.
    cap = None
    if light_h[3] == 0:         # the plane beyond P that faces the light most, as B's exit face of S_c
        m = np.eye(3)[int(np.argmax(np.abs(light_h[:3])))] * np.sign(light_h[:3][np.argmax(np.abs(light_h[:3]))])
        cap = (m.tolist(), float((v @ m).max()) + 10.0)
    h = hull.brep(cap)
    assert_closed_convex(h)
    if light_h[3]:
        # P's vertices on some facet hidden from the light, and the light.
        hidden = {i for g in hull.kept for i in b.loops[g]}
        expected = np.concatenate([v[sorted(hidden)], p[None]])
        assert sorted(map(tuple, np.round(h.vertices, 12))) == sorted(map(tuple, np.round(expected, 12)))
    else:
        assert np.isclose(max(np.array(h.vertices) @ np.array(cap[0])), cap[1])


def test_a_point_light_inside_the_body_gives_the_body():
    b, _ = hull_case(None)
    inside = np.append(np.array(b.vertices).mean(axis=0), 1.0)
    hull = light_hull(b, inside, TOL)
    assert hull.sides == [] and hull.brep() is b
    assert len(hull.normals) == len(b.normals)


def test_a_body_whose_loops_do_not_close_still_gets_hull_planes():
    """Facets sharing two vertices stand in for the edges of loops that do not
    close: the half-spaces still hold P and its light rays, and the hull has
    no boundary to offer (the caller falls back to enumeration)."""
    b, _ = hull_case(None)
    light_h = LIGHTS["point outside"]
    broken = brep.Brep(b.vertices, b.normals, b.offsets, [list(loop) for loop in b.loops])
    broken.loops[0].reverse()                  # one facet turned inside out: its edges run the wrong way
    hull = light_hull(broken, light_h, TOL)
    assert hull.sides is None
    with pytest.raises(brep.OpenCut):
        hull.brep()
    v = np.array(b.vertices)
    p = light_h[:3]
    along = (v + np.linspace(0.0, 1.0, 7)[:, None, None] * (p - v)).reshape(-1, 3)
    assert np.all(along @ hull.normals.T - hull.offsets <= 1e-9)
    assert len(hull.normals) == len(light_hull(b, light_h, TOL).normals)


def test_a_section_has_every_corner_of_the_clip_and_nothing_outside_it():
    """ConvexPolytope.section (the extent of a clip without its faces): every
    vertex of P ∩ H is among its points and every point is in P ∩ H, for random
    half-spaces and for pyramids through an apex (a map's window)."""
    rng = np.random.default_rng(1)
    checked = 0
    for trial in range(300):
        p = ConvexPolytope.box(BOX_LO, BOX_HI, TOL)
        for _ in range(3):
            n = rng.normal(size=(1, 3))
            p = p.clip(n, [rng.uniform(0.2, 1.5) * np.linalg.norm(n)])
        n = rng.normal(size=(int(rng.integers(1, 6)), 3))
        o = rng.uniform(-0.5, 1.5, len(n)) * np.linalg.norm(n, axis=1)
        if trial % 3 == 0:
            o = n @ (rng.normal(size=3) * 4.0)
        clipped, section = p.clip(n, o), p.section(n, o)
        if clipped is None:
            continue
        checked += 1
        assert section is not None
        gap = np.linalg.norm(clipped.vertices[:, None] - section[None], axis=2).min(axis=1)
        assert gap.max() <= 1e-9
        assert np.all(clipped.contains(section, 1e-9))
    assert checked > 100


@pytest.mark.parametrize("light_h", [
    np.array([2.0, 0.5, 1.0, 1.0]),            # a point light in the plane of the box's top facet
    np.array([2.0, 1.0, 1.0, 1.0]),            # ... and on the line of one of its edges
    np.array([1.0, 0.0, 0.0, 0.0]),            # a sun along x: four facets parallel to its rays
    np.array([0.6, 0.8, 0.0, 0.0]),            # a sun in the xy plane: the top and bottom facets hold it
])
def test_facets_holding_the_light_grow_over_their_sides(light_h):
    """A facet whose plane holds the light (a point light in its plane, a sun
    parallel to it) takes its sides into its own loop: the hull is closed and
    no two of its facets share a plane."""
    b = ConvexPolytope.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], TOL).brep()
    hull = light_hull(b, light_h, TOL)
    assert hull.holding
    cap = None
    if light_h[3] == 0:
        axis = int(np.argmax(np.abs(light_h[:3])))
        m = np.eye(3)[axis] * np.sign(light_h[axis])
        cap = (m.tolist(), float(np.max(np.array(b.vertices) @ m)) + 3.0)
    h = hull.brep(cap)
    assert_closed_convex(h)
    planes = np.round(np.c_[np.array(h.normals), np.array(h.offsets)], 9)
    assert len(np.unique(planes, axis=0)) == len(planes), "two facets in one plane"
    v = np.array(b.vertices)
    target = light_h[:3] / light_h[3] if light_h[3] else v + 5.0 * light_h[:3]
    along = (v + np.linspace(0.0, 1.0, 7)[:, None, None] * (target - v)).reshape(-1, 3)
    assert np.all(along @ hull.normals.T - hull.offsets <= 1e-9)


def test_a_cut_through_a_facet_loop_left_open_says_so():
    """A loop that skips a vertex (as a degenerate enumeration can leave one)
    breaks the cap's chain: the cut says OpenCut, so the caller falls back to
    vertex enumeration, instead of failing with a lookup error."""
    cube = brep.hexahedron([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0)])
    found = 0
    for f in range(6):
        for skip in range(4):
            loops = [list(loop) for loop in cube.loops]
            del loops[f][skip]
            broken = brep.Brep(cube.vertices, cube.normals, cube.offsets, loops)
            for axis in range(3):
                normal = [1.0 if k == axis else 0.0 for k in range(3)]
                try:
                    brep.cut(broken, normal, 0.5, TOL)
                except brep.OpenCut:
                    found += 1
    assert found > 0
