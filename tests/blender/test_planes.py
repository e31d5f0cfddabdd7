"""addon.scene.planes and the operator that uses it: planes of interest from selected
faces and from objects, on a small built scene (a floor, a wall, a table slab, a small
cube and a camera); and that plane_optimal is exact on the plane the user picked."""
import importlib
import math
from dataclasses import replace

import bpy
import numpy as np
import pytest


@pytest.fixture(scope="module")
def planes_mod(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.scene.planes")


@pytest.fixture(scope="module")
def warp(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.warp")


def _box_mesh(name, lo, hi):
    me = bpy.data.meshes.new(name)
    verts = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    me.from_pydata(verts, [], faces)
    me.update()
    return me


def _grid_mesh(name, size, cuts):
    """A flat square grid in local XY (many coplanar faces)."""
    me = bpy.data.meshes.new(name)
    xs = np.linspace(-size / 2, size / 2, cuts + 1)
    verts = [(x, y, 0.0) for y in xs for x in xs]
    faces = [(j * (cuts + 1) + i, j * (cuts + 1) + i + 1, (j + 1) * (cuts + 1) + i + 1, (j + 1) * (cuts + 1) + i)
             for j in range(cuts) for i in range(cuts)]
    me.from_pydata(verts, [], faces)
    me.update()
    return me


@pytest.fixture
def room(fresh_scene):
    sc = fresh_scene
    objs = {}

    def link(name, data, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1)):
        ob = bpy.data.objects.new(name, data)
        sc.collection.objects.link(ob)
        ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
        objs[name] = ob
        return ob

    link("Floor", _grid_mesh("Floor", 20.0, 8), location=(0, 0, 0.0))
    link("Wall", _grid_mesh("Wall", 20.0, 4), location=(0, 10, 5), rotation=(math.radians(90), 0, 0))
    link("Table", _box_mesh("Table", (-1.0, -0.6, 0.7), (1.0, 0.6, 0.75)), location=(0, 2, 0))
    link("Cube", _box_mesh("Cube", (-0.2, -0.2, 0.0), (0.2, 0.2, 0.4)), location=(3, 1, 0), scale=(1, 1, 2))
    cam = bpy.data.cameras.new("Cam")
    c = link("Cam", cam, location=(0, -9, 4), rotation=(math.radians(68), 0, 0))
    sc.camera = c
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 640, 360, 100
    sun = bpy.data.lights.new("Sun", "SUN")
    link("Sun", sun, rotation=(math.radians(40), 0, math.radians(30)))
    bpy.context.view_layer.update()
    yield sc, objs
    for ob in objs.values():
        data = ob.data
        bpy.data.objects.remove(ob)
        if isinstance(data, bpy.types.Mesh):
            bpy.data.meshes.remove(data)
        elif isinstance(data, bpy.types.Camera):
            bpy.data.cameras.remove(data)
        elif isinstance(data, bpy.types.Light):
            bpy.data.lights.remove(data)


def _select_faces(ob, predicate):
    me = ob.data
    for p in me.polygons:
        n = ob.matrix_world.to_3x3() @ p.normal
        p.select = bool(predicate(np.array(n), np.array(ob.matrix_world @ p.center)))
    me.update()


def test_planes_from_selected_faces(room, planes_mod):
    sc, objs = room
    table, cube = objs["Table"], objs["Cube"]
    _select_faces(table, lambda n, c: n[2] > 0.99)                  # the table top
    _select_faces(cube, lambda n, c: abs(n[0]) > 0.99)               # the cube's two x faces
    planes = planes_mod.planes_from_selected_faces([table, cube])
    assert len(planes) == 3
    top = [p for p in planes if p.normal[2] > 0.99]
    assert len(top) == 1 and top[0].offset == pytest.approx(0.75)
    ext = top[0].extent
    assert np.allclose(ext.min(axis=0)[:2], [-1.0, 1.4]) and np.allclose(ext.max(axis=0)[:2], [1.0, 2.6])
    sides = sorted(p.offset * np.sign(p.normal[0]) for p in planes if abs(p.normal[0]) > 0.99)
    assert sides == pytest.approx([2.8, 3.2])
    # nothing selected: no plane
    _select_faces(table, lambda n, c: False)
    _select_faces(cube, lambda n, c: False)
    assert planes_mod.planes_from_selected_faces([table, cube]) == []


def test_planes_from_objects(room, planes_mod):
    sc, objs = room
    planes = planes_mod.planes_from_objects([objs["Floor"], objs["Wall"], objs["Table"]])
    assert len(planes) == 3
    floor, wall, table = planes
    assert np.allclose(floor.normal, [0, 0, 1]) and floor.offset == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(np.ptp(floor.extent, axis=0), [20, 20, 0])          # 64 grid faces merged
    assert abs(wall.normal[1]) == pytest.approx(1.0) and abs(wall.offset) == pytest.approx(10.0)
    assert np.allclose(table.normal, [0, 0, 1]) and table.offset == pytest.approx(0.75)   # the top, not the bottom
    # the same plane from two objects becomes one
    both = planes_mod.planes_from_objects([objs["Floor"], objs["Floor"]])
    assert len(both) == 1


def _select_only(names):
    for ob in bpy.context.scene.objects:
        ob.select_set(ob.name in names)
    bpy.context.view_layer.objects.active = bpy.context.scene.objects[names[0]] if names else None


def _link_mesh(sc, objs, name, verts, faces, location=(0, 0, 0), scale=(1, 1, 1)):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], faces)
    me.update()
    ob = bpy.data.objects.new(name, me)
    sc.collection.objects.link(ob)
    ob.location, ob.scale = location, scale
    objs[name] = ob
    bpy.context.view_layer.update()
    return ob


def _triangulated_grid(size, cuts, lift=lambda v: v):
    """A square grid in local XY, each cell two triangles; ``lift`` maps the (N, 3) vertices."""
    xs = np.linspace(-size / 2, size / 2, cuts + 1)
    verts = lift(np.array([(x, y, 0.0) for y in xs for x in xs]))
    at = lambda i, j: j * (cuts + 1) + i
    tris = [t for j in range(cuts) for i in range(cuts)
            for t in ((at(i, j), at(i + 1, j), at(i + 1, j + 1)), (at(i, j), at(i + 1, j + 1), at(i, j + 1)))]
    return verts, tris


def test_an_object_gives_its_largest_flat_surface_not_its_largest_polygon(room, lixel):
    """A studio set in one mesh: a triangulated 10 m floor (200 triangles of 0.5 m²) and a
    10 x 3 m backdrop quad. The floor is the surface shadows fall on; its largest polygon is
    the backdrop."""
    sc, objs = room
    verts, tris = _triangulated_grid(10.0, 10)
    backdrop = [(-5, 5, 0), (5, 5, 0), (5, 5, 3), (-5, 5, 3)]
    _link_mesh(sc, objs, "Studio", list(verts) + backdrop, tris + [tuple(range(len(verts), len(verts) + 4))],
               location=(0, 0, 0.25))
    _select_only(["Studio"])
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    (plane,) = sc.lixel.planes
    np.testing.assert_allclose(plane.normal, (0, 0, 1), atol=1e-6)
    np.testing.assert_allclose(plane.point, (0, 0, 0.25), atol=1e-6)      # on the floor, in its middle
    assert plane.source == "Studio (200 faces)"


def test_a_flat_floor_is_one_plane_and_a_folded_one_two(room, lixel):
    """The float32 vertices of a tilted 20 m floor of 20,000 triangles lying 2.8 km from the
    origin (an imported survey) tilt its faces apart by up to 1.8e-4 rad: still one plane
    (COPLANAR_ANGLE). A 0.1° fold is two."""
    sc, objs = room
    c, s_ = math.cos(0.3), math.sin(0.3)
    tilt = lambda v: v @ np.array([[1, 0, 0], [0, c, s_], [0, -s_, c]])
    _link_mesh(sc, objs, "Far", *_triangulated_grid(20.0, 100, lambda v: tilt(v) + (2000, 2000, 0)))
    fold = math.radians(0.1)
    folded = lambda v: np.where(v[:, 1:2] > 0, v @ np.array([[1, 0, 0], [0, math.cos(fold), math.sin(fold)],
                                                             [0, -math.sin(fold), math.cos(fold)]]), v)
    _link_mesh(sc, objs, "Folded", *_triangulated_grid(2.0, 4, folded))
    found = {}
    for name in ("Far", "Folded"):
        _select_only([name])
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="SELECT")
        try:
            assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")
        found[name] = [tuple(p.normal) for p in sc.lixel.planes]
    assert len(found["Far"]) == 1
    np.testing.assert_allclose(found["Far"][0], tilt(np.array([0.0, 0.0, 1.0])), atol=1e-6)
    assert len(found["Folded"]) == 2


def test_an_object_without_a_plane_is_refused_by_name_and_nothing_changes(room, lixel):
    sc, objs = room
    quad = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    _select_only(["Floor"])
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    _link_mesh(sc, objs, "Squashed", quad, [(0, 1, 2, 3)], scale=(0, 1, 1))
    broken = _link_mesh(sc, objs, "Broken", quad, [(0, 1, 2, 3)])
    broken.data.vertices[2].co.x = float("nan")
    for name in ("Squashed", "Broken"):
        _select_only(["Floor", name])
        with pytest.raises(RuntimeError, match=f"Lixel: {name}.* has no plane .*: fix its vertices"):
            bpy.ops.lixel.planes_from_selection()
        assert [p.source for p in sc.lixel.planes] == ["Floor (64 faces)"]


def test_a_picked_table_top_keeps_its_extent_so_its_map_covers_only_the_top(room, lixel, warp, planes_mod):
    """Chong & Gortler §3: a plane of interest's map need only cover the part of the plane
    that matters. Unbounded, the table top's plane cut the whole view at its height: a
    642 x 261 map instead of 164 x 27."""
    sc, objs = room
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    _select_only(["Table"])
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    (stored,) = sc.lixel.planes
    corners = np.array(stored.extent[:stored.corners])
    assert stored.corners == 4
    np.testing.assert_allclose(corners.min(axis=0), (-1.0, 1.4, 0.75), atol=1e-6)
    np.testing.assert_allclose(corners.max(axis=0), (1.0, 2.6, 0.75), atol=1e-6)
    dg = bpy.context.evaluated_depsgraph_get()
    view, light, bounds = describe.describe_scene(sc, dg)
    opts = replace(sc.lixel.to_settings().warp, shadow_map_size=(1024, 1024))
    picked = warp.compute("plane_optimal", view, light, bounds, opts).maps[0]
    exact = planes_mod.planes_from_objects([objs["Table"]], dg)
    expect = warp.compute("plane_optimal", view, light, bounds, replace(opts, planes=tuple(exact))).maps[0]
    assert picked.size == expect.size and picked.size[0] * picked.size[1] < 1024 * 1024 / 100
    np.testing.assert_allclose(picked.matrix, expect.matrix, rtol=1e-6, atol=1e-9)


def test_the_picked_floor_gives_an_exact_plane_map(room, lixel, warp):
    """On the plane of interest every pixel maps to one lixel (Chong & Gortler §2), for the
    plane the operator took from the selected floor."""
    sc, objs = room
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    _select_only(["Floor"])
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    dg = bpy.context.evaluated_depsgraph_get()
    view, light, bounds = describe.describe_scene(sc, dg)
    opts = replace(sc.lixel.to_settings().warp, shadow_map_size=(1024, 1024))
    setup = warp.compute("plane_optimal", view, light, bounds, opts)
    assert [m.role for m in setup.maps] == ["plane:0", "fallback"]
    floor_map = setup.maps[0]
    # a floor point's texel is its pixel shifted by whole texels (one lixel per pixel)
    pts = np.array([[0.5, -2.0, 0.0], [-3.0, 0.0, 0.0], [2.0, 4.0, 0.0]])
    h = np.column_stack([pts, np.ones(3)])
    lc, vc = h @ floor_map.matrix.T, h @ view.world_to_clip.T
    texel = (lc[:, :2] / lc[:, 3:4] + 1) / 2 * np.array(floor_map.size)
    pixel = (vc[:, :2] / vc[:, 3:4] + 1) / 2 * np.array(view.resolution)
    shift = texel - pixel
    assert np.allclose(shift, np.round(shift[0]), atol=1e-6)
    assert np.all(setup.map_index(pts, view) == 0)
