"""The warp sees what the camera sees (issue 12): B focused on the visible region.

A ``VisibleRegion`` (per screen tile, the eye-depth interval of what is seen)
comes from a depth pre-pass in the render engine and from a coarse ray cast
against the boxes without Blender. The claims: the region holds every visible
point (not only the sampled ones), B built on it still holds every caster that
can shadow one (the independent judge, tests/warp/test_independent_judge.py,
runs with this default), z_n is the nearest visible eye depth, and
``focus="view"`` is exactly the unfocused B of before.
"""
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from addon.measure.box_scene import visible_points
from addon.warp import (METHODS, SceneBounds, WarpOptions, compute, focused_body, intersection_body,
                        region_from_boxes)
from addon.cli.config import parse_config
from addon.warp.culling import BoxIndex
from addon.warp.geometry import clip_halfspaces, clip_volume_corners_h, ortho_matrix
from addon.measure.box_scene import ray_boxes
from addon.warp.rays import ray_index
from addon.warp.types import EmptyBodyError, View, WarpError
from addon.warp.visibility import (BOX_SAMPLES, TileDepths, VisibleRegion, eye_depth_from_window, grid_may_meet,
                                   region_from_window_depth, sample_rays, tile_edges, tile_reduce, unproject)
from hard_cases import EMPTY_CASES, HARD_CASES, camera, point, sun, town

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = {p.stem: p for p in sorted((ROOT / "examples").glob("*.json"))}
CASES = [name for name in HARD_CASES if name not in EMPTY_CASES]


def _example(name):
    view, light, scene, _ = parse_config(json.loads(EXAMPLES[name].read_text()))
    return view, light, scene


def _jittered_points(view, scene, samples, seed):
    """Visible points through randomly placed pixels (not on any grid the region sampled)."""
    rng = np.random.default_rng(seed)
    shift = rng.uniform(-0.5, 0.5, size=2)
    nx, ny = samples
    x = np.clip((np.arange(nx) + 0.5 + shift[0]) / nx * 2 - 1, -1, 1)
    y = np.clip((np.arange(ny) + 0.5 + shift[1]) / ny * 2 - 1, -1, 1)
    gx, gy = np.meshgrid(x, y)
    near = unproject(view, gx, gy, np.full(gx.size, view.near))
    far = unproject(view, gx, gy, np.full(gx.size, view.far))
    d = far - near
    length = np.linalg.norm(d, axis=1)
    t, _, _ = ray_boxes(near, d / length[:, None], length, scene.receivers)
    hit = np.isfinite(t)
    return near[hit] + t[hit, None] * (d[hit] / length[hit, None])


# ----------------------------------------------------------------------------- the region holds what is seen

@pytest.mark.parametrize("name", list(EXAMPLES))
def test_the_visible_region_contains_every_pixels_surface_point_on_the_examples(name):
    view, light, scene = _example(name)
    region = region_from_boxes(view, scene)
    for seed, samples in ((0, (160, 90)), (1, (211, 117))):
        pts = _jittered_points(view, scene, samples, seed)
        assert len(pts) > 1000
        assert region.contains(view, pts).all()


@pytest.mark.parametrize("case", CASES)
def test_the_focused_r_contains_every_pixels_surface_point_on_hard_cases(case):
    """R (B's visible part, what z_n and the fit come from) holds every visible
    point the independent judge's rays find."""
    view, light, scene = HARD_CASES[case]
    try:
        body = focused_body(view, light, scene)
    except EmptyBodyError:
        pytest.skip("nothing visible is lit")
    pts, _ = visible_points(view, scene, (128, 72))
    if light.type == "SPOT":
        lit = np.einsum("ij,j->i", light.rays_to(pts), light.direction) >= math.cos(light.spot_angle / 2)
        pts = pts[lit]
    assert body.visible is not None and body.visible.contains(view, pts).all()
    r = body.visible_polytope
    assert r.contains(pts - body.origin, 1e-6 * body.scale).all()


def test_a_box_smaller_than_the_ray_spacing_is_still_held():
    """A pole thinner than the ray spacing, far in front of the ground, misses
    every ray: its whole depth range still enters the tiles it overlaps."""
    view = camera([0.0, -30.0, 3.0], [0.0, 30.0, 0.0])
    ground = [[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]
    pole = [[0.31, -20.0, 0.0], [0.33, -19.98, 4.0]]           # 2 cm wide at 10 m: far below one ray spacing
    scene = SceneBounds.from_boxes(np.array([ground, pole]))
    region = region_from_boxes(view, scene)
    pts = _jittered_points(view, SceneBounds.from_boxes(np.array([pole])), (1280, 720), 0)
    assert len(pts) > 0 and region.contains(view, pts).all()


def test_ground_seen_past_a_box_in_the_image_corner_beyond_the_outermost_ray_is_held():
    """A wall fills the image but for a strip at its left and top edges, narrower than half a cell: the outermost
    ray, through the corner cell's centre, hits the wall; the ground behind it shows in the image corner."""
    view = camera([0.0, 0.0, 10.0], forward=[0.0, math.cos(0.75), -math.sin(0.75)])
    nx, ny = BOX_SAMPLES
    x, y = -1 + 0.5 / nx, 1 - 0.5 / ny                          # a quarter cell in from the image's top-left corner
    a, b = (unproject(view, [x], [y], [d])[0] for d in (view.near, view.far))
    edge = a + (5.0 - a[1]) / (b[1] - a[1]) * (b - a)           # where that ray meets the wall's front (y = 5)
    ground = [[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]
    scene = SceneBounds.from_boxes(np.array([ground, [[edge[0], 5.0, 0.0], [50.0, 6.0, edge[2]]]]))
    rays = unproject(view, [-1 + 1 / nx, -1], [1 - 1 / ny, 1], [view.near] * 2)
    towards = unproject(view, [-1 + 1 / nx, -1], [1 - 1 / ny, 1], [view.far] * 2) - rays
    _, box, _ = ray_boxes(rays, towards / np.linalg.norm(towards, axis=1)[:, None], [view.far] * 2, scene.receivers)
    assert box.tolist() == [1, 0]                                # outermost ray: the wall; the corner: the ground
    pts, _ = visible_points(view, scene, (960, 540))
    assert region_from_boxes(view, scene).contains(view, pts).all()


def test_a_blender_objects_box_hides_nothing_behind_it():
    """A Blender object's bounds need not be filled (chess pieces spread over a board, a hollow building): the ground
    seen through the empty parts of such a box is held. A box scene's box is solid: there the box hides the ground,
    and its faces are the receivers' surface."""
    view = camera([0.0, 0.0, 3.0], forward=[0.0, math.cos(0.3), -math.sin(0.3)])
    ground = [[-50.0, -50.0, -0.1], [50.0, 200.0, 0.0]]
    pieces = [[-5.0, 4.0, 0.0], [5.0, 8.0, 4.0]]                   # the bounds of a few pieces in the view's middle
    scene = SceneBounds(np.array([ground, pieces]), np.array([ground, pieces]), solid=False)
    through, _ = visible_points(view, SceneBounds.from_boxes(np.array([ground])), (480, 270))
    behind = view.eye_depth(through) > 8.0
    assert behind.sum() > 1000                                     # ground seen past the far side of the pieces
    region = region_from_boxes(view, scene)
    assert region.contains(view, through).all() and region.surface is None
    solid = region_from_boxes(view, SceneBounds.from_boxes(scene.receivers))
    assert not solid.contains(view, through[behind]).all() and solid.surface is not None


def test_what_shows_through_a_gap_narrower_than_the_ray_spacing_is_held():
    """Two walls fill the view above the ground but for a slit between two columns of rays, a fifth of their spacing
    wide: no ray passes it, yet the ground and a far wall 50 m behind show through it (a silhouette: the rays either side hit
    different boxes, so whatever lies behind within their square is held)."""
    view = camera([0.0, 0.0, 1.5], forward=[0.0, 1.0, 0.0])
    nx, _ = BOX_SAMPLES
    x = -1 + 2 * 20 / nx                                        # midway between ray columns 19 and 20
    left, right = (unproject(view, [x + s * 0.2 / nx], [0.0], [10.0])[0][0] for s in (-1, 1))
    ground, far_wall = [[-90.0, -5.0, -0.1], [90.0, 90.0, 0.0]], [[-90.0, 60.0, 0.0], [90.0, 61.0, 90.0]]
    walls = [[[-90.0, 10.0, 0.0], [left, 10.05, 90.0]], [[right, 10.0, 0.0], [90.0, 10.05, 90.0]]]
    scene = SceneBounds.from_boxes(np.array([ground, far_wall, *walls]))
    origins, dirs, length = sample_rays(view, BOX_SAMPLES)
    t = ray_boxes(origins, dirs, length, scene.receivers)[0]
    assert (view.eye_depth(origins + t[:, None] * dirs) <= 10.05).all()         # every ray meets a wall or the ground
    slit = _jittered_points(view, scene, (1280, 720), 0)
    slit = slit[view.eye_depth(slit) > 10.05]                                     # seen through the slit
    assert len(slit) > 100 and region_from_boxes(view, scene).contains(view, slit).all()


def test_a_rail_slipping_diagonally_between_the_rays_is_held():
    """A 5 mm rail 20 m ahead of a rolled camera, against the sky: its image crosses the ray grid diagonally, many
    spacings wide and tall, and meets no ray; every square its image meets holds its depths."""
    roll = math.radians(25.0)
    view = camera([0.0, 0.0, 2.0], forward=[0.0, 1.0, 0.0], up=(math.sin(roll), 0.0, math.cos(roll)))
    rail = [[-6.0, 20.0, 3.0], [6.0, 20.005, 3.005]]
    scene = SceneBounds.from_boxes(np.array([[[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]], rail]))
    origins, dirs, length = sample_rays(view, BOX_SAMPLES)
    assert np.isinf(ray_boxes(origins, dirs, length, np.array([rail]))[0]).all()
    pts, _ = visible_points(view, SceneBounds.from_boxes(np.array([rail])), (1920, 1080))
    assert len(pts) > 100 and region_from_boxes(view, scene).contains(view, pts).all()


def test_nothing_visible_is_an_empty_body():
    view = camera([0.0, 0.0, 5.0], forward=[0.0, 0.0, 1.0])               # looking at the sky
    with pytest.raises(EmptyBodyError, match="sees no shadow receiver"):
        focused_body(view, sun([0.3, 0.2, -1.0]), town())


# ----------------------------------------------------------------------------- z_n and Δz from visibility

def test_z_n_is_the_nearest_visible_eye_depth():
    """A camera 40 m up looks down at 45° over flat ground: the nearest visible
    point is where the image's bottom edge meets the ground, far beyond the
    near plane (0.1 m). z_n is that depth (within the region's padding), never more."""
    height, tilt, fov = 40.0, math.radians(45.0), 60.0
    view = camera([0.0, 0.0, height], [0.0, height / math.tan(tilt), 0.0], fov=fov, far=500.0)
    flat = town(flat=True, size=400.0)
    mast = [[-2.0, 60.0, 0.0], [2.0, 62.0, 60.0]]              # a tower in view: S_r reaches up past the camera
    scene = SceneBounds.from_boxes(np.concatenate([flat.casters, [mast]]))
    # The bottom edge's ray leaves at tilt + φ below the horizon; its eye depth is the distance times cos φ.
    phi = math.radians(fov / 2)
    nearest = height / math.sin(tilt + phi) * math.cos(phi)
    for method in ("lispsm", "gmnpr", "glpr"):
        setup = compute(method, view, sun([0.3, 0.6, -0.7]), scene, WarpOptions(shadow_map_size=1024))
        z_n = setup.diagnostics.extra["z_n"]
        assert setup.diagnostics.extra["focus"] == "scene boxes"
        assert 0.9 * nearest <= z_n <= nearest
    old = compute("lispsm", view, sun([0.3, 0.6, -0.7]), scene, WarpOptions(shadow_map_size=1024, focus="view"))
    assert old.diagnostics.extra["z_n"] < 0.5 * nearest and old.diagnostics.extra["focus"] == "view frustum"


def test_delta_z_ends_at_the_farthest_visible_depth():
    """Looking at a wall 20 m ahead in a 100 m frustum: z_n + Δz is the wall, not the far plane."""
    view = camera([0.0, 0.0, 2.0], [0.0, 20.0, 2.0])
    wall = [[-30.0, 20.0, -1.0], [30.0, 21.0, 30.0]]
    ground = [[-60.0, -60.0, -0.1], [60.0, 60.0, 0.0]]
    scene = SceneBounds.from_boxes(np.array([wall, ground]))
    setup = compute("lispsm", view, sun([0.5, 0.5, -0.7]), scene, WarpOptions(shadow_map_size=1024))
    z_f = setup.diagnostics.extra["z_n"] + setup.diagnostics.extra["delta_z"]
    assert 20.0 <= z_f <= 30.0          # (the ground's plane, extended one ray spacing up its grazing slope)


def test_the_focused_body_is_inside_the_unfocused_one():
    """Focusing only drops what nobody sees: B and R shrink, never grow."""
    for case in ("sun_behind_camera", "sun_1deg_above_horizon", "point_light_behind_camera", "spot_over_scene",
                 "camera_inside_scene_box"):
        view, light, scene = HARD_CASES[case]
        old, new = intersection_body(view, light, scene), focused_body(view, light, scene)
        assert old.contains(new.vertices, 1e-6 * old.scale).all()
        assert old.visible_polytope.contains(new.visible_vertices - old.origin, 1e-6 * old.scale).all()


def test_focus_view_is_the_unfocused_body_of_before():
    view, light, scene = HARD_CASES["sun_behind_camera"]
    body = intersection_body(view, light, scene)
    for method in METHODS:
        options = WarpOptions(shadow_map_size=1024, focus="view")
        a = compute(method, view, light, scene, options)
        b = compute(method, view, light, scene, options, body=body)
        assert a.diagnostics.extra["focus"] == "view frustum"
        for ma, mb in zip(a.maps, b.maps):
            assert np.array_equal(ma.matrix, mb.matrix)


def test_a_given_region_is_used_and_reported():
    view, light, scene = HARD_CASES["sun_behind_camera"]
    region = region_from_boxes(view, scene)
    given = type(region)(region.tiles, "depth pre-pass")
    setup = compute("uniform", view, light, scene, WarpOptions(shadow_map_size=1024), visible=given)
    assert setup.diagnostics.extra["focus"] == "depth pre-pass"
    assert setup.diagnostics.extra["visible_depth_range"] == given.depth_range


def test_focus_is_an_option_with_a_clear_message():
    with pytest.raises(WarpError, match="focus must be one of"):
        WarpOptions(focus="everything")


# ----------------------------------------------------------------------------- depth buffers to regions

@pytest.mark.parametrize("ortho", [False, True])
def test_window_depth_converts_to_the_eye_depths_it_came_from(ortho):
    """A synthetic depth buffer of known eye depths (float32, as read back)
    gives tiles whose intervals hold those depths, ulp padding included."""
    base = camera([0.0, -10.0, 3.0], [0.0, 10.0, 0.0], near=0.1, far=1000.0, res=(96, 64))
    view = base if not ortho else View(base.camera_to_world, ortho_matrix(-8, 8, -5, 5, 0.1, 1000.0), 0.1,
                                       1000.0, (96, 64), True)
    rng = np.random.default_rng(3)
    eye = rng.uniform(5.0, 900.0, size=(64, 96))
    p = view.projection
    z_ndc = (p[2, 2] * -eye + p[2, 3]) / (p[3, 2] * -eye + p[3, 3])
    window = ((z_ndc + 1) / 2).astype(np.float32)
    window[:16, :16] = 1.0                                      # nothing drawn in the first tile
    assert np.allclose(eye_depth_from_window(view, (z_ndc + 1) / 2), eye)
    region = region_from_window_depth(view, window, tile=16)
    t = region.tiles
    assert not t.seen[0, 0] and t.seen.sum() == t.seen.size - 1
    for j in range(t.near.shape[0]):
        for i in range(t.near.shape[1]):
            block = eye[16 * j:16 * j + 16, 16 * i:16 * i + 16][window[16 * j:16 * j + 16, 16 * i:16 * i + 16] < 1]
            if block.size:
                assert t.near[j, i] <= block.min() and t.far[j, i] >= block.max()
                assert t.samples[j, i] == block.size


def test_tiles_take_the_min_and_max_of_their_samples():
    view = camera([0.0, 0.0, 2.0], [0.0, 10.0, 2.0], res=(64, 32))
    near = np.full((32, 64), np.inf)
    far = np.full((32, 64), -np.inf)
    near[3, 5], far[3, 5] = 4.0, 6.0
    near[4, 6], far[4, 6] = 2.0, 3.0
    region = VisibleRegion(TileDepths(tile_edges(64, 8), tile_edges(32, 8), *tile_reduce(near, far, 8)), "given")
    assert region.tiles.seen.sum() == 1
    assert region.depth_range == (2.0, 6.0)
    x0, x1, y0, y1 = region.screen
    assert (x0, x1, y0, y1) == (-1.0, -0.75, -1.0, -0.5)


# ----------------------------------------------------------------------------- rays

def test_rays_through_the_culling_index_equal_rays_against_every_box():
    rng = np.random.default_rng(1)
    centre = rng.uniform(-50, 50, (700, 3))
    half = rng.uniform(0.1, 3, (700, 3))
    boxes = np.stack([centre - half, centre + half], 1)
    boxes[:5, :, 2] = [[0.0, 0.0]] * 5                      # flat boxes: rays in their plane
    index = BoxIndex(boxes)
    origins = rng.uniform(-60, 60, (500, 3))
    origins[:20, 2] = 0.0
    dirs = rng.normal(size=(500, 3))
    dirs[:20, 2] = 0.0                                      # parallel to the flat boxes' plane
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    t_max = np.full(500, 150.0)
    t, box, _ = ray_boxes(origins, dirs, t_max, boxes)
    t2, box2 = ray_index(origins, dirs, t_max, index)
    assert np.array_equal(t, t2)
    assert np.array_equal(np.where(np.isfinite(t), box, -1), box2)
    sel = index.select(np.array([[0.0, 0.0, 1.0]]), np.array([10.0]))     # only boxes reaching below z = 10
    t3, box3 = ray_index(origins, dirs, t_max, index, sel)
    t4, b4, _ = ray_boxes(origins, dirs, t_max, boxes[sel.mask])
    assert np.array_equal(t3, t4)
    assert np.array_equal(box3, np.where(np.isfinite(t4), np.flatnonzero(sel.mask)[b4], -1))


def test_the_grids_rays_tested_only_against_the_clusters_they_may_meet_find_the_same_hits():
    """``grid_may_meet`` leaves out only (ray, cluster) pairs that cannot meet: the same hit distances and boxes, bit
    for bit, as testing every cluster, for cameras among 1,500 boxes (five of them inside one), perspective and
    orthographic, with near planes up to 4 m."""
    rng = np.random.default_rng(5)
    centre, half = rng.uniform(-60, 60, (1500, 2)), rng.uniform(0.3, 3, (1500, 2))
    boxes = np.stack([np.c_[centre - half, np.zeros(1500)], np.c_[centre + half, rng.uniform(1, 12, 1500)]], axis=1)
    index = BoxIndex(np.concatenate([[[[-70, -70, -0.2], [70, 70, 0.0]]], boxes]))
    views = [camera([*rng.uniform(-50, 50, 2), rng.choice([0.5, 1.7, 6.0, 40.0])],
                    forward=[*rng.normal(size=2), rng.uniform(-1.0, 0.2)], near=float(rng.choice([0.01, 0.5, 4.0])),
                    far=float(rng.uniform(20, 200))) for _ in range(12)]
    views += [dataclasses.replace(v, projection=ortho_matrix(-20, 20, -12, 12, v.near, v.far), orthographic=True)
              for v in views[:4]]
    tested = []
    for view in views:
        origins, dirs, length = sample_rays(view, BOX_SAMPLES)
        selection = index.select(*clip_halfspaces(view.world_to_clip))
        may_meet = grid_may_meet(view, index, BOX_SAMPLES)
        every = ray_index(origins, dirs, length, index, selection)
        tested.append((may_meet.mean(), np.isfinite(every[0]).mean()))
        culled = ray_index(origins, dirs, length, index, selection, may_meet)
        assert np.array_equal(every[0], culled[0]) and np.array_equal(every[1], culled[1])
    share, hit = np.array(tested).T
    assert share.max() < 0.5 and (hit > 0.2).sum() >= 12      # (most pairs left out, most views see boxes)


def test_a_ray_from_inside_a_box_meets_the_inner_wall_and_its_normal_faces_back_along_the_ray():
    """A camera standing in a room sees the wall it looks at, turned towards it: the hit face's normal
    (the face the ray leaves by), not the axis it would have entered by from outside."""
    room = np.array([[[0.0, 0.0, 0.0], [10.0, 10.0, 10.0]]])
    origins = np.array([[1.0, 9.0, 5.0], [5.0, 5.0, 9.0], [-5.0, 5.0, 5.0]])
    dirs = np.array([[0.6, 0.8, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    t, box, normal = ray_boxes(origins, dirs, np.full(3, 100.0), room)
    np.testing.assert_allclose(t, [1.25, 9.0, 5.0])
    np.testing.assert_array_equal(normal, [[0, -1, 0], [0, 0, 1], [-1, 0, 0]])   # the last from outside


def test_clip_halfspaces_hold_exactly_what_a_matrix_maps_into_its_clip_volume():
    """-w <= x, y, z <= w as six world half-spaces, for a view frustum and for a volume through infinity."""
    rng = np.random.default_rng(2)
    through_infinity = rng.normal(size=(4, 4))
    assert np.sum(clip_volume_corners_h(through_infinity)[:, 3] < 0) == 1         # one corner behind
    for matrix in (camera(np.array([0.0, -5.0, 2.0]), np.array([0.0, 1.0, -0.3])).world_to_clip, through_infinity):
        n, o = clip_halfspaces(matrix)
        p = rng.uniform(-30.0, 30.0, (20000, 3))
        h = np.c_[p, np.ones(len(p))] @ matrix.T
        inside = (h[:, 3] > 0) & np.all(np.abs(h[:, :3]) <= h[:, 3:], axis=1)
        assert 0 < inside.sum() < len(p)
        np.testing.assert_array_equal(np.all(p @ n.T <= o, axis=1), inside)
