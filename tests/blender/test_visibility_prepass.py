"""The warp sees what the camera sees, through the render engine (issue 12).

The engine draws the camera's depth pre-pass first, reads it back per tile and
fits B to it, so z_n is the nearest *visible* depth and the maps hold exactly
what the shading pass shades.
"""
import importlib
import math
from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector

from conftest import remove_objects_and_orphans

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    for name in ("render.engine", "gpu.pipeline", "gpu.visibility", "gpu.context", "gpu.result", "scene.describe",
                 "scene.geometry", "settings", "warp"):
        setattr(m, name.split(".")[-1], importlib.import_module(f"{lixel.__name__}.addon.{name}"))
    return m


def add(scene, name, data):
    ob = bpy.data.objects.new(name, data)
    scene.collection.objects.link(ob)
    return ob


def box_mesh(name, lo, hi):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], [],
                   [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    return me


def overlook(scene, height=30.0):
    """A camera 30 m up looking down at 45° over a 400 m ground with a few
    boxes and a tower in view (the tower makes the unfocused B reach the
    near plane), near 0.1 m, far 300 m, and a sun."""
    ground = bpy.data.meshes.new("Ground")
    ground.from_pydata([(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)], [], [(0, 1, 2, 3)])
    add(scene, "Ground", ground)
    for i, x in enumerate((-8.0, 0.0, 8.0)):
        add(scene, f"Box{i}", box_mesh(f"Box{i}", (x, 25.0, 0.0), (x + 2.0, 27.0, 3.0)))
    add(scene, "Tower", box_mesh("Tower", (-2.0, 36.0, 0.0), (2.0, 38.0, 45.0)))
    cam = add(scene, "Cam", bpy.data.cameras.new("Cam"))
    cam.data.clip_start, cam.data.clip_end = 0.1, 300.0
    cam.location = (0.0, 0.0, height)
    cam.rotation_euler = (Vector((0.0, height, 0.0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    sun = add(scene, "Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(40), 0, math.radians(30))
    scene.render.engine = "LIXEL"
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.resolution_percentage = 100


def render(mods, scene, method="lispsm", **warp):
    settings = mods.settings.LixelSettings(method=method)
    if warp:
        from dataclasses import replace
        settings = replace(settings, warp=replace(settings.warp, **warp))
    dg = scene.view_layers[0].depsgraph
    dg.update()
    mods.context.ensure_gpu_context()
    return mods.engine.render_depsgraph(dg, settings=settings, read=mods.result.ANALYSIS)


def test_the_engine_fits_the_warp_to_its_depth_prepass(mods, fresh_scene):
    """z_n is the nearest visible eye depth the pre-pass saw (the bottom edge of
    the image on the ground), not the near plane; focus says where it came from."""
    overlook(fresh_scene)
    last = render(mods, fresh_scene)
    d = last["setup"].diagnostics
    res = last["result"]
    nearest_shaded = float(res.eye_depth[res.covered].min())
    assert d.extra["focus"] == "depth pre-pass"
    near, far = d.extra["visible_depth_range"]
    assert near <= nearest_shaded and near > 0.97 * nearest_shaded
    assert far >= float(res.eye_depth[res.covered].max())
    assert 0.9 * nearest_shaded <= d.extra["z_n"] <= nearest_shaded
    assert "visibility" in res.timings and "camera_prepass" in res.timings
    old = render(mods, fresh_scene, focus="view")
    assert old["setup"].diagnostics.extra["focus"] == "view frustum"
    assert old["setup"].diagnostics.extra["z_n"] < 0.1 * nearest_shaded


def test_the_engine_reads_the_seen_surface_back_only_for_a_method_that_reads_it(mods, fresh_scene, monkeypatch):
    """Issue 15's wasted work (``warp.methods.reads_surface``): a stable cascade, or a one-split one whose λ guard
    does not act, does not read the pre-pass's surface back and gets the maps it got when it did; the adaptive
    cascade reads it, and so does a one-split cascade whose warps the guard weighs by the shadow edges seen
    (``engine.looks_for_edges``)."""
    overlook(fresh_scene)
    read, asked, force = mods.visibility.region_from_frame, [], []

    def spy(frame, *args, surface=False, **kwargs):
        asked.append(surface)
        return read(frame, *args, surface=surface or bool(force), **kwargs)

    def maps(**warp):
        mods.engine.shared_warps().clear()                   # (an unchanged frame would take the last one's warp)
        return [(m.role, m.matrix.tolist()) for m in render(mods, fresh_scene, "cascade", **warp)["setup"].maps]

    monkeypatch.setattr(mods.visibility, "region_from_frame", spy)
    for warp in (dict(cascade_stable=True), dict(cascade_splits=1, lambda_guard="off")):
        without = maps(**warp)
        assert asked[-1] is False
        force.append(True)
        assert maps(**warp) == without                       # the surface read back as before: the same maps
        force.clear()
    for warp in (dict(), dict(cascade_splits=1)):
        maps(**warp)
        assert asked[-1] is True


def overlooked_frame(mods, scene, read):
    """The overlooked scene's view, light, bounds and a ShadowFrame of its camera reading back ``read``."""
    overlook(scene)
    dg = scene.view_layers[0].depsgraph
    dg.update()
    mods.context.ensure_gpu_context()
    geometry = mods.geometry.GeometryCache().update(dg)
    view, light, bounds = mods.describe.describe_scene(scene, dg, instances=geometry.instances)
    return view, light, bounds, mods.pipeline.ShadowFrame(geometry, view, read=read)


def test_the_prepass_region_holds_every_shaded_point(mods, fresh_scene):
    """Every pixel the shading pass shades (its world position) lies in the
    region read back from the depth target that pass reuses."""
    view, light, bounds, frame = overlooked_frame(mods, fresh_scene, {"world_position", "covered", "map_index"})
    frame.camera_prepass()
    region, seconds = mods.visibility.region_from_frame(frame)
    assert seconds >= 0 and region.source == "depth pre-pass"
    body = mods.warp.focused_body(view, light, bounds, visible=region)
    setup = mods.warp.compute("uniform", view, light, bounds, mods.warp.WarpOptions(shadow_map_size=256), body=body)
    shadow = mods.settings.ShadowSettings()
    frame.draw_maps(setup, shadow, body)
    frame.shade(light, setup, shadow)
    out = frame.finish()
    points = out.world_position[out.covered]
    assert len(points) > 1000
    assert region.contains(view, points, tol=1e-5).all()
    assert (out.map_index[out.covered] == 0).all()               # and the map serves every one of them


def test_the_prepass_surface_holds_the_shaded_point_of_each_sampled_pixel(mods, fresh_scene):
    """plane_optimal's seen surface read back from the same pre-pass: at 160 x 90 one sample per drawn pixel, row
    by row, whose segment (its depth's float32 precision) holds the point the shading pass shades there."""
    view, light, bounds, frame = overlooked_frame(mods, fresh_scene, {"world_position", "covered"})
    region, _ = mods.visibility.region_from_frame(frame, surface=True)
    body = mods.warp.focused_body(view, light, bounds, visible=region)
    setup = mods.warp.compute("uniform", view, light, bounds, mods.warp.WarpOptions(shadow_map_size=256), body=body)
    frame.draw_maps(setup, mods.settings.ShadowSettings(), body)
    frame.shade(light, setup, mods.settings.ShadowSettings())
    out = frame.finish()
    points = out.world_position[out.covered].astype(np.float64)
    a, b = region.surface[:, 0], region.surface[:, 1]
    assert len(points) == len(a) > 1000
    t = np.clip(np.einsum("ij,ij->i", points - a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0.0, 1.0)
    gap = np.linalg.norm(a + t[:, None] * (b - a) - points, axis=1)
    assert (gap <= 1e-4 * np.linalg.norm(points - view.position, axis=1)).all()


def test_the_prepass_surface_samples_carry_their_faces_normals(mods, fresh_scene):
    """The cascade scores its maps by the footprint at the seen receivers: each sampled pixel's normal, unpacked
    from the pre-pass's octahedral code, is its face's (the overlooked scene's faces are axis-aligned, most of them
    the ground's)."""
    view, light, bounds, frame = overlooked_frame(mods, fresh_scene, {"covered"})
    region, _ = mods.visibility.region_from_frame(frame, surface=True)
    n = region.normals
    assert n.shape == (len(region.surface), 3) and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert (np.abs(n).max(axis=1) > 1 - 1e-6).all()                        # within about 1e-3 rad of an axis
    assert (np.abs(n[:, 2]) > 1 - 1e-6).sum() > 0.5 * len(n)


@contextmanager
def sample_scene(name: str):
    """The sample scene ``name`` (sample_blends/) appended, at 320x180 and its first frame; removed after."""
    with bpy.data.libraries.load(str(ROOT / "sample_blends" / f"{name}.blend")) as (src, dst):
        dst.scenes = list(src.scenes)
    scene = dst.scenes[0]
    try:
        scene.render.resolution_x, scene.render.resolution_y = 320, 180
        scene.render.resolution_percentage = 100
        scene.frame_set(scene.frame_start)
        yield scene
    finally:
        for s in dst.scenes:
            remove_objects_and_orphans(s)
            bpy.data.scenes.remove(s)


def test_on_the_terrain_view_z_n_comes_from_the_depth_prepass(mods):
    """The terrain sample: nothing is visible nearer than about 128 m, with the
    camera's near plane at 1 m. z_n follows what is seen (issue 12's diagnosis)."""
    with sample_scene("terrain") as scene:
        last = render(mods, scene, "glpr")
        d = last["setup"].diagnostics
        assert d.extra["focus"] == "depth pre-pass"
        assert d.extra["z_n"] > 100.0
        cam = scene.camera.data
        assert cam.clip_start <= 1.0
        # GLPR's own λ at these depths over-warps: the guard acts and says so
        assert any(what.endswith("λ guard") for what, _ in d.fallbacks)


def test_the_gpu_tile_reduction_equals_the_read_back_one(mods, fresh_scene):
    """The engine reduces the pre-pass per tile on the GPU; reading the whole
    depth back and reducing in numpy gives the same region, tile for tile."""
    overlook(fresh_scene)
    fresh_scene.render.resolution_x, fresh_scene.render.resolution_y = 173, 97     # partial tiles at the edges
    cam = fresh_scene.camera                                                       # up to the horizon: some sky
    cam.rotation_euler = (Vector((0.0, 150.0, 25.0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    dg = fresh_scene.view_layers[0].depsgraph
    dg.update()
    mods.context.ensure_gpu_context()
    geometry = mods.geometry.GeometryCache().update(dg)
    view, _, _ = mods.describe.describe_scene(fresh_scene, dg, instances=geometry.instances)
    frame = mods.pipeline.ShadowFrame(geometry, view)
    frame.camera_prepass()
    gpu_region, _ = mods.visibility.region_from_frame(frame)
    cpu_region, _ = mods.visibility.region_from_frame(frame, on_gpu=False)
    a, b = gpu_region.tiles, cpu_region.tiles
    assert a.near.shape == b.near.shape == (7, 11)
    np.testing.assert_array_equal(a.x_edges, b.x_edges)
    np.testing.assert_array_equal(a.y_edges, b.y_edges)
    np.testing.assert_array_equal(a.seen, b.seen)
    np.testing.assert_array_equal(a.samples, b.samples)
    np.testing.assert_array_equal(a.near[a.seen], b.near[b.seen])
    np.testing.assert_array_equal(a.far[a.seen], b.far[b.seen])
    assert 0 < a.seen.sum() < a.seen.size                                 # ground below, sky above


def test_the_shadow_edges_found_by_a_first_look_are_where_the_shadows_change(mods, fresh_scene):
    """The λ guard weighs the warp by where shadow edges fall on what is seen (docs/papers.md, the λ guard, part 7):
    ``shadow_edges`` marks the tiles whose surface samples lie at an edge of a coarse uniform map's shadows. Against
    the shadows a fine uniform map renders, every tile it marks holds or touches an edge, and it finds most edge
    tiles; faces turned from the light (in their own shadow) and unshadowed ground mark nothing."""
    view, light, bounds, frame = overlooked_frame(mods, fresh_scene, {"shadow_raw", "covered"})
    region, _ = mods.visibility.region_from_frame(frame, surface=True)
    options = mods.warp.WarpOptions(shadow_map_size=2048)
    body = mods.warp.focused_body(view, light, bounds, options, region)
    found = mods.visibility.shadow_edges(frame, region, body, light, bounds, options).tiles.edges
    setup = mods.warp.compute("uniform", view, light, bounds, options, body=body)
    frame.draw_maps(setup, mods.settings.ShadowSettings(), body)
    frame.shade(light, setup, mods.settings.ShadowSettings())
    out = frame.finish()
    shadow, seen = out.shadow_raw >= 0.5, out.covered
    change = np.zeros_like(shadow)
    for a, b in (((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                 ((slice(None), slice(1, None)), (slice(None), slice(None, -1)))):
        step = (shadow[a] != shadow[b]) & seen[a] & seen[b]
        change[a] |= step
        change[b] |= step
    truth = mods.warp.visibility.tile_counts(change, mods.visibility.PIXEL_TILE) > 0
    near_truth = truth.copy()
    for axis in (0, 1):
        near_truth |= np.roll(truth, 1, axis) | np.roll(truth, -1, axis)
    assert found.shape == truth.shape and truth.sum() >= 4
    assert (found > 0).sum() >= 0.7 * truth.sum()
    assert not ((found > 0) & ~near_truth).any()


@pytest.mark.parametrize("name", ["chess", "floor_wall", "telephoto"])
def test_without_a_prepass_the_boxes_region_holds_every_point_the_engine_shades(mods, name):
    """The panel, its overlays and the scripts fit B without a pre-pass, to a ray cast against the objects' boxes.
    A Blender object need not fill its box (chess's pieces, telephoto's town), so the region must not stop at a box's
    face: before, it ended at 3.5 m of chess's 20 m, and a cascade's far split lost its shadows there."""
    with sample_scene(name) as scene:
        dg = scene.view_layers[0].depsgraph
        mods.context.ensure_gpu_context()
        out = mods.engine.render_depsgraph(dg, read={"world_position", "covered"})["result"]
        view, _, bounds = mods.describe.describe_scene(scene, dg)
        points = out.world_position[out.covered]
        assert len(points) > 1000
        assert mods.warp.region_from_boxes(view, bounds).contains(view, points, tol=1e-5).all()


def test_the_first_look_knows_which_way_the_shadow_edges_run(mods, fresh_scene):
    """``shadow_edges`` also gives each edge sample its edge's direction (the first look's 3 x 3 taps' gradient carried
    onto the sample's plane through the map's Jacobian), which the cascade's pick weighs its maps by: on the ground
    below axis-aligned boxes under a sun, a shadow edge is a top edge's image (along x or y) or a vertical edge's
    (along the sun's ground direction), and the directions found lie along those."""
    view, light, bounds, frame = overlooked_frame(mods, fresh_scene, set())
    region, _ = mods.visibility.region_from_frame(frame, surface=True)
    options = mods.warp.WarpOptions(shadow_map_size=2048)
    body = mods.warp.focused_body(view, light, bounds, options, region)
    found = mods.visibility.shadow_edges(frame, region, body, light, bounds, options)
    d = found.edge_directions
    on_ground = np.any(d != 0, axis=1) & (np.abs(found.normals[:, 2]) > 0.99)
    assert d.shape == found.normals.shape and on_ground.sum() >= 20
    np.testing.assert_allclose(np.linalg.norm(d[on_ground], axis=1), 1.0)
    sun = light.direction[:2] / np.linalg.norm(light.direction[:2])
    off = [np.degrees(np.arccos(np.clip(np.abs(d[on_ground, :2] @ a), 0.0, 1.0))) for a in ([1, 0], [0, 1], sun)]
    off = np.min(off, axis=0)
    assert np.median(off) < 5.0 and np.percentile(off, 80) < 15.0, np.percentile(off, [50, 80, 100])


@pytest.mark.parametrize("kind", ["SUN", "POINT"])
def test_a_point_light_gets_the_first_looks_edges_but_its_lambda_guard_does_not_weigh_them(mods, fresh_scene, kind):
    """The cascade's pick weighs its single maps by the shadow edges' directions (``partition.receivers.filter_losses``)
    for a point light too: ``fit_warp`` takes the first look and hands the cascade each edge sample's direction, but
    not the per-tile edge weights the λ guard weighs its warps by (a point light's warped cube faces rendered worse
    with them: docs/papers.md, the λ guard, part 7); a sun's cascade gets both. A point light's one-map LiSPSM takes the
    directions too, to turn its texel axes off the edges (``warp_frustum.edge_turned``), and no weights. plane_optimal
    takes the edge samples under either light, to price its default plane by its share of the edges
    (``plane_map.default_plane``), and no edge weights (no guard)."""
    overlook(fresh_scene)
    lamp = fresh_scene.objects["Sun"]
    lamp.data.type = kind
    lamp.location = (1.0, -4.0, 36.0)
    dg = fresh_scene.view_layers[0].depsgraph
    dg.update()
    mods.context.ensure_gpu_context()
    geometry = mods.geometry.GeometryCache().update(dg)
    view, light, bounds = mods.describe.describe_scene(fresh_scene, dg, instances=geometry.instances)
    assert light.type == kind

    def seen(method):
        frame = mods.pipeline.ShadowFrame(geometry, view, read=set())
        frame.camera_prepass()
        options = mods.settings.LixelSettings(method=method).warp
        return mods.engine.fit_warp(frame, light, bounds, options, method)[0].visible

    cascade = seen("cascade")
    assert cascade.edge_directions is not None and np.any(cascade.edge_directions != 0, axis=1).sum() >= 20
    assert (cascade.edge_weights() is None) == (kind == "POINT")
    lispsm = seen("lispsm")
    assert lispsm.edge_directions is not None and (lispsm.edge_weights() is None) == (kind == "POINT")
    plane_optimal = seen("plane_optimal")
    assert plane_optimal.edge_directions is not None and plane_optimal.edge_weights() is None


def test_a_point_light_among_what_is_seen_takes_no_first_look_its_one_map_turn_cannot_use(mods, fresh_scene,
                                                                                          monkeypatch):
    """A point light among what the camera sees needs several cube faces, and a one-map turn
    (``warp_frustum.edge_turned``) is all the first look serves a point light's LiSPSM: ``fit_warp`` skips the look
    there (its cost, 90-120 ms of a cold frame), while the cascade, whose pick reads the edges, still takes it."""
    overlook(fresh_scene)
    lamp = fresh_scene.objects["Sun"]
    lamp.data.type = "POINT"
    lamp.location = (0.0, 22.0, 2.0)
    dg = fresh_scene.view_layers[0].depsgraph
    dg.update()
    mods.context.ensure_gpu_context()
    geometry = mods.geometry.GeometryCache().update(dg)
    view, light, bounds = mods.describe.describe_scene(fresh_scene, dg, instances=geometry.instances)
    looked = []
    first_look = mods.engine.first_look
    monkeypatch.setattr(mods.engine, "first_look", lambda *args: looked.append(args[-1]) or first_look(*args))

    def fit(method):
        frame = mods.pipeline.ShadowFrame(geometry, view, read=set())
        frame.camera_prepass()
        return mods.engine.fit_warp(frame, light, bounds, mods.settings.LixelSettings(method=method).warp, method)

    body, setup, _ = fit("lispsm")
    assert len(setup.maps) > 1 and looked == [] and body.visible.edge_directions is None
    body, setup, _ = fit("cascade")
    assert looked == ["cascade"] and np.any(body.visible.edge_directions != 0, axis=1).sum() >= 20
