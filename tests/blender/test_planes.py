"""addon.scene.planes: planes of interest from selected faces, from objects and
detected automatically, on a small built scene (a floor, a wall, a table slab,
a small cube and a camera); and that plane_optimal is exact on them."""
import importlib
import math

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


def test_detect_planes_finds_the_floor_and_the_wall_not_the_small_faces(room, planes_mod, lixel):
    sc, objs = room
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    dg = bpy.context.evaluated_depsgraph_get()
    view = describe.describe_view(sc.camera, dg, sc)
    found = planes_mod.detect_planes(dg, view)
    assert 1 <= len(found) <= planes_mod.DETECT_MAX_PLANES
    assert np.allclose(found[0].normal, [0, 0, 1]) and found[0].offset == pytest.approx(0.0, abs=1e-9)
    cov = [planes_mod.image_coverage(p, view) for p in found]
    assert all(c >= planes_mod.DETECT_MIN_COVERAGE for c in cov) and cov == sorted(cov, reverse=True)
    assert any(abs(p.normal[1]) > 0.99 and abs(abs(p.offset) - 10) < 1e-6 for p in found)   # the wall
    assert not any(abs(p.offset - 0.75) < 1e-6 for p in found)                                # the small table top
    one = planes_mod.detect_planes(dg, view, max_planes=1)
    assert len(one) == 1 and one[0].name == found[0].name and one[0].offset == found[0].offset
    assert planes_mod.detect_planes(dg, view, min_coverage=0.99) == []


def test_detected_planes_give_exact_plane_maps(room, planes_mod, lixel, warp):
    sc, objs = room
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    dg = bpy.context.evaluated_depsgraph_get()
    view, light, bounds = describe.describe_scene(sc, dg)
    found = planes_mod.detect_planes(dg, view)
    opts = warp.WarpOptions(shadow_map_size=(1024, 1024), planes=planes_mod.as_warp_planes(found))
    setup = warp.compute("plane_optimal", view, light, bounds, opts)
    roles = [m.role for m in setup.maps]
    assert roles[:len(found)] == [f"plane:{i}" for i in range(len(found))] and roles[-1] == "fallback"
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
