"""Convex polytopes (``addon.warp.polyhedron``) and the light hull built on
them (``addon.warp.light_hull``).

A clip leaves a closed convex polytope whose faces lie on their planes and
turn counter-clockwise seen from outside, holding exactly the points of both
bodies; the section of P by a convex Q (its facets and edges) has every
vertex of P ∩ Q among its points and none outside it; hull(P ∪ light) holds P,
the light and every segment between them."""
import math

import numpy as np
import pytest

from addon.warp import polyhedron
from addon.warp.geometry import UNIT_CUBE_CORNERS
from addon.warp.light_hull import light_hull
from addon.warp.polyhedron import ConvexPolytope, Edges, OpenCut, box_edges, box_offsets, clip_segments, section_points

from test_body import AWKWARD_SAMPLES, BOX_HI, BOX_LO, awkward_cuts

TOL = 1e-10 * 6.0


def newell(points: np.ndarray) -> np.ndarray:
    """Newell's normal of a polygon: outward for a counter-clockwise loop seen from outside."""
    n = np.zeros(3)
    for a, b in zip(points, np.roll(points, -1, axis=0)):
        n += [(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])]
    return n


def assert_closed_convex(p: ConvexPolytope, tol: float = 1e-9):
    """Every directed edge has its reverse in another face (closed, consistently
    oriented), Euler V - E + F = 2, every vertex is used, each loop lies on its
    facet's plane and turns counter-clockwise about its outward normal, and every
    vertex is inside every facet's half-space."""
    owner = {}
    for f, loop in enumerate(p.loops):
        for i in range(len(loop)):
            assert (loop[i - 1], loop[i]) not in owner, "an edge appears twice in one direction"
            owner[(loop[i - 1], loop[i])] = f
    for (a, b), f in owner.items():
        assert (b, a) in owner and owner[(b, a)] != f, "open edge"
    assert len(p.vertices) - len(owner) // 2 + len(p.loops) == 2
    assert sorted({i for loop in p.loops for i in loop}) == list(range(len(p.vertices)))
    assert np.allclose(np.linalg.norm(p.normals, axis=1), 1.0)
    for n, o, loop in zip(p.normals, p.offsets, p.loops):
        assert len(loop) >= 3
        assert np.all(np.abs(p.vertices[list(loop)] @ n - o) <= tol)
        area = newell(p.vertices[list(loop)])
        assert area @ n >= -tol * np.linalg.norm(area)
    assert np.all(p.vertices @ p.normals.T - p.offsets <= tol)


def box() -> ConvexPolytope:
    return ConvexPolytope.box(BOX_LO, BOX_HI, TOL)


def unit(n, o):
    n, o = np.atleast_2d(np.asarray(n, dtype=float)), np.atleast_1d(np.asarray(o, dtype=float))
    length = np.linalg.norm(n, axis=1)
    return n / length[:, None], o / length


def test_a_box_and_a_frustum_have_outward_counter_clockwise_faces():
    assert_closed_convex(box())
    projection = np.array([[1.2, 0, 0, 0], [0, 2.0, 0, 0], [0, 0, -1.02, -0.2], [0, 0, -1, 0]])
    h = np.c_[UNIT_CUBE_CORNERS, np.ones(8)] @ np.linalg.inv(projection).T
    assert_closed_convex(ConvexPolytope.hexahedron(h[:, :3] / h[:, 3:], TOL))


def test_a_hexahedron_of_mirrored_corners_is_the_same_solid():
    corners = np.array(UNIT_CUBE_CORNERS, dtype=float) * [2.0, 1.0, 0.5] + [1.0, -3.0, 2.0]
    for c in (corners, corners * [-1.0, 1.0, 1.0]):
        p = ConvexPolytope.hexahedron(c, TOL)
        assert_closed_convex(p)
        b = ConvexPolytope.box(c.min(axis=0), c.max(axis=0), TOL)
        planes = {tuple(np.round(np.r_[n, o], 12)) for n, o in zip(p.normals, p.offsets)}
        assert planes == {tuple(np.round(np.r_[n, o], 12)) for n, o in zip(b.normals, b.offsets)}


def test_a_clip_holds_exactly_the_points_of_the_half_spaces():
    rng = np.random.default_rng(11)
    pts = rng.uniform(BOX_LO, BOX_HI, (3000, 3))
    for _ in range(200):
        p = box()
        inside = np.ones(len(pts), dtype=bool)
        for _ in range(int(rng.integers(1, 7))):
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
            o = float(rng.uniform(-0.5, 2.0))
            cut = p.clip([n], [o])
            inside &= pts @ n <= o
            if cut is None:
                assert not inside.any()
                break
            p = cut
        else:
            assert_closed_convex(p)
            clear = np.abs(pts @ p.normals.T - p.offsets).min(axis=1) > 1e-9
            assert np.array_equal(p.contains(pts[clear], 0.0), inside[clear])


def test_a_half_space_holding_the_body_keeps_it_and_one_beyond_it_leaves_nothing():
    p = box()
    assert p.clip([[1.0, 0.0, 0.0]], [BOX_HI[0] + 1.0]) is p
    assert p.clip([[1.0, 0.0, 0.0]], [BOX_HI[0]]) is p                 # along a face
    assert p.clip([[1.0, 0.0, 0.0]], [BOX_LO[0]]) is None              # leaves only a face
    assert p.clip([[-1.0, 0.0, 0.0]], [-BOX_HI[0] - 1.0]) is None


def test_a_cut_through_vertices_and_edges_shares_them():
    """A plane through two opposite edges of the box halves it: no new vertex,
    the four on the plane shared by both halves' new facets."""
    d = BOX_HI - BOX_LO
    n = np.array([d[1], -d[0], 0.0]) / math.hypot(d[0], d[1])
    half = box().clip([n], [float(n @ BOX_LO)])
    assert_closed_convex(half)
    assert len(half.vertices) == 6 and len(half.loops) == 5


def test_awkward_cuts_give_closed_bodies_holding_the_half_spaces():
    """On the seeded degenerate cuts of test_body (a plane through a corner,
    tilted 1e-9 rad from a face, repeated within 1e-14), the clip is closed
    whenever the face walk orders it, and it holds the right points."""
    rng = np.random.default_rng(20261122)
    pts = np.random.default_rng(0).uniform(BOX_LO, BOX_HI, (2000, 3))
    for _ in range(AWKWARD_SAMPLES // 3):
        n, o = unit(*awkward_cuts(rng))
        p = box().clip(n, o)
        if p is None:
            assert not np.any((pts @ n.T - o).max(axis=1) < -1e-9)
            continue
        d = (pts @ n.T - o).max(axis=1)
        clear = np.abs(d) > 1e-6
        assert np.array_equal(p.contains(pts[clear], 0.0), d[clear] < 0)


def test_a_cut_the_walk_cannot_order_falls_back_to_vertex_enumeration(monkeypatch):
    def refuse(*args):
        raise OpenCut("refused for the test")
    walked = box().clip(*unit([[1.0, 1.0, 1.0]], [1.0]))
    monkeypatch.setattr(polyhedron, "_cut", refuse)
    enumerated = box().clip(*unit([[1.0, 1.0, 1.0]], [1.0]))
    assert_closed_convex(enumerated)
    assert sorted(map(tuple, np.round(enumerated.vertices, 9))) == sorted(map(tuple, np.round(walked.vertices, 9)))


def test_a_facet_loop_left_open_makes_the_cut_fall_back():
    """A loop that skips a vertex (as a degenerate enumeration can leave one)
    breaks the new facet's chain: the clip falls back to vertex enumeration
    instead of failing with a lookup error, and gives the true clip."""
    cube = ConvexPolytope.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], TOL)
    for f in range(6):
        for skip in range(4):
            loops = [list(loop) for loop in cube.loops]
            del loops[f][skip]
            broken = ConvexPolytope(cube.vertices, cube.normals, cube.offsets, tuple(loops), TOL)
            for axis in range(3):
                half = broken.clip([np.eye(3)[axis]], [0.5])
                assert np.isclose(half.vertices[:, axis].max(), 0.5)


# ----------------------------------------------------------------------------- sections

def random_polytope(rng) -> ConvexPolytope:
    p = box()
    for _ in range(3):
        n = rng.normal(size=3)
        p = p.clip([n / np.linalg.norm(n)], [rng.uniform(0.2, 1.5)])
    return p


def assert_section(points: np.ndarray, part: ConvexPolytope | None, tol: float = 1e-9):
    """Every vertex of ``part`` is among ``points`` and every point is in it."""
    if part is None:
        assert len(points) == 0
        return
    gap = np.linalg.norm(part.vertices[:, None] - points[None], axis=2).min(axis=1)
    assert gap.max() <= tol
    assert np.all(part.contains(points, tol))


def test_a_section_by_boxes_has_every_corner_of_each_clip_and_nothing_outside_it():
    rng = np.random.default_rng(1)
    for _ in range(60):
        p = random_polytope(rng)
        lo = rng.uniform(-2.0, 1.0, (5, 3))
        hi = lo + rng.uniform(0.0, 2.0, (5, 3))
        hi[0, 2] = lo[0, 2]                                          # one box flat
        points, owner = section_points(p, np.broadcast_to(polyhedron.BOX_NORMALS, (5, 6, 3)),
                                       box_offsets(lo, hi), box_edges(lo, hi), tol=0.0)
        assert np.all(np.diff(owner) >= 0)
        for k in range(5):
            part = p.clip(polyhedron.BOX_NORMALS, box_offsets(lo[k], hi[k] + [0.0, 0.0, 1e-9 * (k == 0)]))
            if k == 0:
                if part is not None:
                    assert np.all(np.abs(points[owner == 0][:, 2] - lo[0, 2]) <= 1e-12)
                continue
            assert_section(points[owner == k], part)


def test_a_section_by_pyramids_from_an_apex_has_every_corner_of_each_clip():
    """Four-sided pyramids from the origin (a point light's cube faces, a map's
    window): their sides' planes and their corner rays, which are unbounded
    edges."""
    rng = np.random.default_rng(2)
    for _ in range(60):
        p = random_polytope(rng).translated(rng.normal(size=3) * 2.0)
        forward = rng.normal(size=(3, 3))
        sides, rays = [], []
        for f in forward:
            f /= np.linalg.norm(f)
            u = np.cross(f, [0.3, 0.5, 0.8])
            u /= np.linalg.norm(u)
            v = np.cross(f, u)
            w = rng.uniform(0.2, 1.5)
            corners = [f + w * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            normals = [np.cross(corners[i], corners[i - 1]) for i in range(4)]
            sides.append([n / np.linalg.norm(n) for n in normals])
            rays.append(corners)
        sides, rays = np.array(sides), np.array(rays)
        points, owner = section_points(p, sides, np.zeros((3, 4)), Edges(np.zeros_like(rays), rays, np.full((3, 4), np.inf)),
                                       tol=0.0)
        for k in range(3):
            assert_section(points[owner == k], p.clip(sides[k], np.zeros(4)))


def test_a_plane_section_is_the_polygon_of_the_edge_crossings_counter_clockwise():
    """P's section by a plane lists, in order about the plane's normal, exactly
    the points where P's edges cross it (on planes through vertices too)."""
    rng = np.random.default_rng(3)
    for trial in range(200):
        p = random_polytope(rng)
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        offset = float(p.vertices[trial % len(p.vertices)] @ n) if trial % 4 == 0 else float(rng.uniform(-1, 1))
        section = polyhedron.plane_section(p, n, offset)
        half = p.clip([n], [offset])
        if section is None:
            assert half is None or half is p or np.ptp(half.vertices @ n) <= 1e-9
            continue
        height = p.vertices @ n - offset
        a, b = p.edges.T
        crossed = height[a] * height[b] < 0
        t = height[a][crossed] / (height[a][crossed] - height[b][crossed])
        crossings = p.vertices[a[crossed]] + t[:, None] * (p.vertices[b[crossed]] - p.vertices[a[crossed]])
        hull = polyhedron.convex_polygon_on_plane(np.concatenate([crossings, p.vertices[np.abs(height) <= p.tol]]),
                                                  n, p.tol)
        assert np.abs(section @ n - offset).max() <= 1e-9 and newell(section) @ n > 0
        assert len(section) == len(hull)
        assert np.linalg.norm(section[:, None] - hull[None], axis=2).min(axis=1).max() <= 1e-9


def test_cyrus_beck_keeps_a_segment_in_a_facet_plane_and_drops_a_parallel_one_outside():
    normals, offsets = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), np.array([1.0, 2.0])
    segments = Edges(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.5], [0.0, 0.0, 0.0]]),
                     np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [4.0, 0.0, 0.0]]), np.ones(3))
    lo, hi = clip_segments(segments, normals, offsets)
    assert (lo[0], hi[0]) == (0.0, 1.0)                  # in the plane z = 1: kept
    assert lo[1] > hi[1]                                 # parallel to it, beyond: nothing
    assert (lo[2], hi[2]) == (0.0, 0.5)                  # x <= 2 cuts it half way


# ----------------------------------------------------------------------------- the light hull

def hull_case():
    rng = np.random.default_rng(4)
    p = ConvexPolytope.box([-1.0, -2.0, -3.0], [2.0, 1.0, 3.0], TOL)
    for _ in range(3):
        n = rng.normal(size=3)
        p = p.clip([n / np.linalg.norm(n)], [0.8])
    return p


LIGHTS = {
    "point outside": np.array([7.0, 5.0, 9.0, 1.0]),
    "point beside": np.array([-9.0, 0.3, 0.2, 1.0]),
    "sun": np.append(np.array([0.3, -0.4, 0.8]) / np.linalg.norm([0.3, -0.4, 0.8]), 0.0),
    "sun along an axis": np.array([0.0, 0.0, 1.0, 0.0]),
}


def cap_beyond(v: np.ndarray, light_h: np.ndarray, gap: float) -> tuple:
    """The plane beyond P that faces a sun most (as B's exit face of S_c)."""
    axis = int(np.argmax(np.abs(light_h[:3])))
    m = np.eye(3)[axis] * np.sign(light_h[axis])
    return m, float((v @ m).max()) + gap


def assert_holds_light_rays(p: ConvexPolytope, light_h, normals, offsets):
    v = p.vertices
    target = light_h[:3] / light_h[3] if light_h[3] else v + 50.0 * light_h[:3]
    along = (v + np.linspace(0.0, 1.0, 7)[:, None, None] * (target - v)).reshape(-1, 3)
    assert np.all(along @ normals.T - offsets <= 1e-9)


@pytest.mark.parametrize("name", LIGHTS)
def test_the_light_hull_holds_the_body_and_its_light_rays(name):
    p, light_h = hull_case(), LIGHTS[name]
    hull = light_hull(p, light_h)
    # Every half-space holds P, and each side passes through the light.
    assert np.all(p.vertices @ hull.normals.T - hull.offsets <= 1e-12)
    sides = hull.normals[len(hull.kept):]
    if light_h[3]:
        light = light_h[:3] / light_h[3]
        assert np.allclose(sides @ light, hull.offsets[len(hull.kept):])
        assert np.all(hull.normals @ light - hull.offsets <= 1e-12)
    else:
        assert np.allclose(sides @ light_h[:3], 0.0)
    assert_holds_light_rays(p, light_h, hull.normals, hull.offsets)
    # As a polytope: closed, with P's vertices not hidden from the light and the light or the cap.
    cap = None if light_h[3] else cap_beyond(p.vertices, light_h, 10.0)
    h = hull.polytope(cap)
    assert_closed_convex(h)
    if light_h[3]:
        hidden = {i for g in hull.kept for i in p.loops[g]}
        expected = np.concatenate([p.vertices[sorted(hidden)], light[None]])
        assert sorted(map(tuple, np.round(h.vertices, 12))) == sorted(map(tuple, np.round(expected, 12)))
    else:
        assert np.isclose(max(h.vertices @ cap[0]), cap[1])


def test_a_point_light_inside_the_body_gives_the_body():
    p = hull_case()
    hull = light_hull(p, np.append(p.centroid, 1.0))
    assert hull.sides == [] and hull.polytope() is p
    assert len(hull.normals) == len(p.normals)


def test_a_body_whose_loops_do_not_close_still_gets_hull_planes():
    """Facets sharing two vertices stand in for the edges of loops that do not
    close: the half-spaces still hold P and its light rays, and the hull has
    no polytope to offer (the caller falls back to enumeration)."""
    p, light_h = hull_case(), LIGHTS["point outside"]
    loops = [list(loop) for loop in p.loops]
    loops[0].reverse()                         # one facet turned inside out: its edges run the wrong way
    broken = ConvexPolytope(p.vertices, p.normals, p.offsets, tuple(loops), TOL)
    hull = light_hull(broken, light_h)
    assert hull.sides is None
    with pytest.raises(OpenCut):
        hull.polytope()
    assert_holds_light_rays(p, light_h, hull.normals, hull.offsets)
    assert len(hull.normals) == len(light_hull(p, light_h).normals)


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
    p = ConvexPolytope.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], TOL)
    hull = light_hull(p, light_h)
    assert hull.holding
    h = hull.polytope(None if light_h[3] else cap_beyond(p.vertices, light_h, 3.0))
    assert_closed_convex(h)
    planes = np.round(np.c_[h.normals, h.offsets], 9)
    assert len(np.unique(planes, axis=0)) == len(planes), "two facets in one plane"
    assert_holds_light_rays(p, light_h, hull.normals, hull.offsets)


def test_merging_points_in_blocks_merges_as_comparing_every_pair(monkeypatch):
    """unique_points compares rows in blocks, each against the points within reach in x (memory stays bounded for a
    mesh outline of 20,000 corners): the same points come out whatever the block, chains of near points included."""
    rng = np.random.default_rng(7)
    tol = 1e-3
    chains = np.cumsum(np.full((40, 3), [0.9e-3, 0.0, 0.0]), axis=0) + rng.integers(0, 3, (40, 3))
    copies = np.repeat(rng.random((300, 3)), 3, axis=0) + rng.normal(0.0, 0.4e-3, (900, 3))
    columns = np.c_[np.full(200, 0.5), rng.random((200, 2))]          # one x: a block's window holds them all
    points = rng.permutation(np.concatenate([chains, copies, columns, copies[:50]]))
    whole = polyhedron.unique_points(points, tol)
    monkeypatch.setattr(polyhedron, "MERGE_PAIRS", 1)
    assert np.array_equal(polyhedron.unique_points(points, tol), whole)
    assert len(points) - 50 > len(whole) > 300
