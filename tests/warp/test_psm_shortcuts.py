"""PSM's exact shortcuts equal the general paths they skip, on random and on
degenerate configurations:

* the two-point cone (the midpoint of the most distant pair of directions,
  accepted by Wolfe's optimality test) equals Wolfe's nearest point, and is
  refused when the cone needs three directions;
* ``LowestInBoxes`` (box edges by facet sign, the region's edges by slabs)
  equals the previous general Cyrus-Beck clipping of both edge sets and the
  least vertex of the region clipped by each box, also for boxes sharing
  planes with the region, flat boxes and region edges lying in box faces;
* the nearest visible depth stops at R's nearest vertex when a receiver box
  about to be measured holds it, and still equals the least depth over every
  receiver box."""
from __future__ import annotations

import math

import numpy as np
import pytest

import addon.warp.post_perspective as post_perspective
from addon.warp import EmptyBodyError, SceneBounds, intersection_body
from addon.warp.polyhedron import ConvexPolytope
from addon.warp.post_perspective import (LowestInBoxes, cone_through, lowest_in_boxes, min_norm_point,
                                          nearest_visible_depth, smallest_cone, two_point_cone_centre)
from bench.warp_speed import city_scene, street_view
from hard_cases import camera, spot, sun


# ----------------------------------------------------------------------------- the two-point cone

def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _cone_by_wolfe(d):
    """smallest_cone's general path: Wolfe's nearest point, then its direction and margin."""
    return cone_through(min_norm_point(d).tolist(), d)


def _random_frame(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q


def _two_point_cone(rng, n, half):
    """n unit directions in a cone of half-angle ``half`` spanned by two of them."""
    a = rng.uniform(0, 2 * math.pi)
    rim = [[math.sin(half) * math.cos(a), math.sin(half) * math.sin(a), math.cos(half)],
           [-math.sin(half) * math.cos(a), -math.sin(half) * math.sin(a), math.cos(half)]]
    tilt = rng.uniform(0, half * 0.98, n - 2)
    turn = rng.uniform(0, 2 * math.pi, n - 2)
    inner = np.column_stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    d = np.concatenate([rim, inner]) @ _random_frame(rng).T
    return d[rng.permutation(n)]


def _three_point_cone(rng, n, half):
    """n unit directions in a cone of half-angle ``half`` that needs three of them
    (120° apart on its rim, so no two are 2·half apart)."""
    a = rng.uniform(0, 2 * math.pi) + np.array([0.0, 2 * math.pi / 3, 4 * math.pi / 3])
    rim = np.column_stack([math.sin(half) * np.cos(a), math.sin(half) * np.sin(a), np.full(3, math.cos(half))])
    tilt = rng.uniform(0, half * 0.5, n - 3)
    turn = rng.uniform(0, 2 * math.pi, n - 3)
    inner = np.column_stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    return np.concatenate([rim, inner]) @ _random_frame(rng).T


def test_two_point_cone_equals_wolfe_and_refuses_three_point_cones():
    rng = np.random.default_rng(41)
    taken = refused = 0
    for t in range(1500):
        n = int(rng.integers(2, 40))
        kind = t % 3
        if kind == 0:
            d = _two_point_cone(rng, n, rng.uniform(0.01, 1.5))
        elif kind == 1 and n >= 3:
            d = _three_point_cone(rng, n, rng.uniform(0.01, 1.5))
        else:                                 # random points in a random cap: either kind
            d = _unit(rng.normal(size=(n, 3)) * rng.uniform(0.05, 1.0) + [0.0, 0.0, 1.0]) @ _random_frame(rng).T
        x = two_point_cone_centre(d)
        if x is None:
            refused += 1
        else:
            taken += 1
            assert np.abs(x - min_norm_point(d)).max() <= 1e-9
        if kind == 0:
            assert x is not None
        elif kind == 1 and n >= 3:
            assert x is None
        k, margin = smallest_cone(d)
        k_ref, margin_ref = _cone_by_wolfe(d)
        assert np.abs(k - k_ref).max() <= 1e-9
        assert margin == pytest.approx(margin_ref, abs=1e-12)
    assert taken > 500 and refused > 400


def test_two_point_cone_of_repeated_and_opposite_directions():
    same = np.tile(_unit([0.3, -0.2, 0.9]), (5, 1))
    k, margin = smallest_cone(same)
    assert np.allclose(k, same[0]) and margin == pytest.approx(1.0)
    opposite = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    k, margin = smallest_cone(opposite)            # the directions surround the origin: no cone
    assert margin == pytest.approx(0.0, abs=1e-12)


# ----------------------------------------------------------------------------- LowestInBoxes

def _lowest_by_cyrus_beck(region, lo, hi, axis):
    """The previous general path: both edge sets clipped by Cyrus-Beck in one pass."""
    edge_axis = np.repeat(np.eye(3), 4, axis=0)[:, None, :]
    edge_start = np.array([[0, j, k] for j in (0, 1) for k in (0, 1)] + [[i, 0, k] for i in (0, 1) for k in (0, 1)]
                          + [[i, j, 0] for i in (0, 1) for j in (0, 1)], dtype=bool)[:, None, :]
    n, o = region.normals, region.offsets
    start = np.where(edge_start, hi, lo)
    step = edge_axis * (hi - lo)
    box_num, box_den = o[:, None, None] - np.inner(n, start), np.inner(n, step)
    loops = region.facet_loops()
    a = [v for loop in loops for v in loop[-1:] + loop[:-1]]
    b = [v for loop in loops for v in loop]
    p, d = region.vertices[a], region.vertices[b] - region.vertices[a]
    pt, dt = p.T[:, :, None], d.T[:, :, None]
    region_num = np.concatenate([hi.T[:, None, :] - pt, pt - lo.T[:, None, :]])
    region_den = np.broadcast_to(np.concatenate([dt, -dt]), region_num.shape)
    rows = max(len(n), 6)
    num = np.zeros((rows, 12 + len(a), len(lo)))
    den = np.zeros_like(num)
    num[: len(n), :12], den[: len(n), :12] = box_num, box_den
    num[:6, 12:], den[:6, 12:] = region_num, region_den
    base = np.concatenate([start @ axis, np.broadcast_to((p @ axis)[:, None], (len(a), len(lo)))])
    rate = np.concatenate([step @ axis, np.broadcast_to((d @ axis)[:, None], (len(a), len(lo)))])
    with np.errstate(over="ignore", invalid="ignore"):
        ratio = np.divide(num, den, out=np.where(num >= 0, np.inf, -np.inf), where=den != 0)
        enter = np.where(den < 0, ratio, -np.inf).max(axis=0, initial=0.0)
        leave = np.where(den >= 0, ratio, np.inf).min(axis=0, initial=1.0)
        value = base + np.where(rate >= 0, enter, leave) * rate
    return np.where(enter <= leave, value, np.inf).min(axis=0)


def _lowest_by_clipping(region, lo, hi, axis):
    """The least vertex of the region clipped by each box (None: no volume in common)."""
    eye = np.eye(3)
    out = []
    for a, b in zip(lo, hi):
        part = region.clip(np.concatenate([eye, -eye]), np.concatenate([b, -a]))
        out.append(None if part is None else float((part.vertices @ axis).min()))
    return out


def _grid_direction(rng):
    """A unit direction along an axis, a face diagonal or a space diagonal."""
    while True:
        v = rng.integers(-1, 2, 3) + 0.0
        if v.any():
            return _unit(v)


def _closed(region) -> bool:
    """Every edge of the facet loops is walked once each way (a closed surface)."""
    walked = [(loop[i - 1], loop[i]) for loop in region.facet_loops() for i in range(len(loop))]
    return sorted(walked) == sorted((b, a) for a, b in walked)


def _random_region(rng):
    while True:
        normals = _unit(rng.normal(size=(int(rng.integers(5, 14)), 3)))
        region = ConvexPolytope.from_halfspaces(normals, rng.uniform(1.0, 3.0, len(normals)), 1e-9)
        if region is not None and _closed(region):
            return region


def _grid_region(rng):
    """An axis-aligned box on a 0.5 grid, some corners cut off: facets and edges that
    boxes on the same grid share planes with, lie in or run parallel to."""
    lo = rng.integers(-4, 0, 3) * 0.5
    hi = rng.integers(1, 5, 3) * 0.5
    region = ConvexPolytope.box(lo, hi, 1e-9)
    for _ in range(int(rng.integers(0, 3))):
        n = _grid_direction(rng) if rng.random() < 0.7 else _unit(rng.normal(size=3))
        cut = region.clip(n[None], np.array([float((region.vertices @ n).max()) - rng.uniform(0.2, 1.0)]))
        region = cut if cut is not None and _closed(cut) else region
    return region


def _grid_boxes(rng, count):
    lo = rng.integers(-6, 6, (count, 3)) * 0.5
    size = rng.integers(0, 5, (count, 3)) * 0.5            # some flat boxes (a zero size)
    return lo, lo + size


@pytest.mark.parametrize("seed", range(6))
def test_lowest_in_boxes_equals_cyrus_beck_and_clipping(seed):
    rng = np.random.default_rng(100 + seed)
    met = 0
    for t in range(30):
        if t % 2:
            region = _random_region(rng)
            centre = rng.uniform(-3, 3, size=(12, 3))
            half = rng.uniform(0.05, 2.5, size=(12, 3))
            lo, hi = centre - half, centre + half
        else:
            region = _grid_region(rng)
            lo, hi = _grid_boxes(rng, 12)
        axis = _unit(rng.normal(size=3)) if t % 3 else _grid_direction(rng)
        got = LowestInBoxes.of(region, axis)(lo, hi)
        assert np.array_equal(got, lowest_in_boxes(region, lo, hi, axis))
        reference = _lowest_by_cyrus_beck(region, lo, hi, axis)
        assert np.array_equal(np.isinf(got), np.isinf(reference))
        finite = np.isfinite(got)
        assert np.abs(got[finite] - reference[finite]).max(initial=0.0) <= 1e-12 * (1 + np.abs(reference[finite]).max(initial=0.0))
        for value, least in zip(got, _lowest_by_clipping(region, lo, hi, axis)):
            if least is not None:
                met += 1
                assert value == pytest.approx(least, abs=1e-9)
    assert met >= 60


def test_lowest_in_boxes_on_a_face_of_the_region():
    """Boxes resting on the region's faces, flat boxes in its facet planes and region
    edges lying in box faces: every case meets the region, at the expected depth."""
    region = ConvexPolytope.box(np.array([0.0, 0.0, 0.0]), np.array([2.0, 2.0, 2.0]), 1e-9)
    axis = _unit([0.2, 0.3, 1.0])
    lo = np.array([[0.0, 0.0, -1.0], [2.0, 0.5, 0.5], [0.5, 0.5, 2.0], [0.0, 0.0, 0.0], [-1.0, -1.0, 1.0], [1.0, 1.0, 0.0]])
    hi = np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 1.0], [1.5, 1.5, 3.0], [2.0, 2.0, 0.0], [0.0, 3.0, 1.0], [1.0, 1.0, 2.0]])
    got = LowestInBoxes.of(region, axis)(lo, hi)
    corner_depth = [float(np.maximum(a, 0.0) @ axis) for a in lo]   # the nearest point: the clamped lower corner
    assert got == pytest.approx(corner_depth, abs=1e-12)
    assert np.allclose(got, _lowest_by_cyrus_beck(region, lo, hi, axis), atol=1e-12)


# ----------------------------------------------------------------------------- the nearest visible depth

def _least_over_every_box(view, body):
    """The nearest visible depth by brute force, and whether R's nearest vertex lies in a receiver box."""
    origin, axis = view.position, -view.world_to_camera[2, :3]
    boxes = body.receiver_boxes
    depths = (body.visible_vertices - origin) @ axis
    coarse = max(float(depths.min()), view.near)
    least = float(lowest_in_boxes(body.visible_polytope, boxes[:, 0] - origin, boxes[:, 1] - origin, axis).min())
    vertex = body.visible_vertices[int(depths.argmin())]
    held = bool(np.any(np.all((boxes[:, 0] <= vertex) & (vertex <= boxes[:, 1]), axis=1)))
    return (max(least, coarse) if math.isfinite(least) else coarse), coarse, held


def _measured_boxes(monkeypatch):
    """Counts the boxes LowestInBoxes measures."""
    measured = []
    call = LowestInBoxes.__call__

    def counting(self, lo, hi):
        measured.append(len(lo))
        return call(self, lo, hi)

    monkeypatch.setattr(post_perspective.LowestInBoxes, "__call__", counting)
    return measured


def test_nearest_visible_depth_stops_at_the_nearest_vertex_of_r_in_a_receiver_box(monkeypatch):
    """Spot lights over the bench's city, moved about the bench's spot: the depth
    is the least over every receiver box, and R's nearest vertex when a receiver
    box holds it, found without measuring any box."""
    measured = _measured_boxes(monkeypatch)
    scene = city_scene(10000)
    rng = np.random.default_rng(5)
    stopped = checked = 0
    for _ in range(40):
        view = street_view()
        light = spot(np.array([-70.0, -70.0, 40.0]) + rng.normal(size=3) * [20, 20, 10],
                     np.array([1.0, 1.0, -0.7]) + rng.normal(size=3) * 0.2, math.radians(rng.uniform(30, 90)))
        try:
            body = intersection_body(view, light, scene)
        except EmptyBodyError:
            continue
        expected, coarse, vertex_held = _least_over_every_box(view, body)
        measured.clear()
        assert nearest_visible_depth(view, light, body) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        if vertex_held:
            assert expected == pytest.approx(coarse, rel=1e-12, abs=1e-12)
            stopped += measured == []          # (a box holding it may wait behind a batch of ties)
        checked += 1
    assert checked >= 30 and stopped >= 3


def test_nearest_visible_depth_in_a_room_measures_nothing(monkeypatch):
    """A camera inside a receiver box (a room) sees it first at the near plane."""
    measured = _measured_boxes(monkeypatch)
    room = np.array([[[-5.0, -5.0, 0.0], [5.0, 5.0, 3.0]], [[-40.0, -40.0, -0.1], [40.0, 40.0, 0.0]],
                     [[1.0, 2.0, 0.0], [2.0, 3.0, 1.0]]])
    view = camera((0.0, -3.0, 1.5), (0.0, 5.0, 1.0), near=0.05, far=30.0)
    light = sun([0.3, 0.2, -1.0])
    body = intersection_body(view, light, SceneBounds.from_boxes(room))
    expected, coarse, vertex_held = _least_over_every_box(view, body)
    assert vertex_held and expected == pytest.approx(view.near)
    measured.clear()
    assert nearest_visible_depth(view, light, body) == pytest.approx(expected, rel=1e-12)
    assert measured == []
