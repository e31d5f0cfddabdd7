"""Geometry-node tooling: the texel attribute the Texel Grid group evaluates
equals numpy's per vertex (explicit homogeneous divide), the frustum group's
mesh is the inverse projection of the unit cube (nothing where a corner is at
w <= 0 and would come out mirrored), both follow the matrices when they change,
and building is idempotent and versioned."""
import importlib
import math
from contextlib import contextmanager

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def nodes(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.nodes")


@pytest.fixture(scope="module")
def wg(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.warp.geometry")


@pytest.fixture
def scene(lixel):
    with active_scene("lixel_nodes") as sc:
        yield sc
    coll = bpy.data.collections.get("Lixel Debug")
    if coll is not None:
        for ob in list(coll.objects):
            bpy.data.objects.remove(ob)
        bpy.data.collections.remove(coll)


@contextmanager
def saved_and_loaded(block, kind: str, path):
    """``block`` (one of ``bpy.data``'s ``kind``) written to a file at ``path`` and loaded back as a copy, removed
    afterwards: what a saved file gives back."""
    bpy.data.libraries.write(str(path), {block})
    with bpy.data.libraries.load(str(path)) as (_, into):
        setattr(into, kind, [block.name])
    loaded = getattr(into, kind)[0]
    try:
        yield loaded
    finally:
        getattr(bpy.data, kind).remove(loaded)


class _Map:
    def __init__(self, matrix, size):
        self.matrix, self.size = np.asarray(matrix, dtype=np.float64), size


class _Setup:
    def __init__(self, *maps):
        self.maps = list(maps)


def perspective_light(wg, eye, target, fov=math.radians(50), near=1.0, far=30.0):
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    world_to_eye = wg.look_along(eye, target - eye, np.array([0.0, 1.0, 0.0]))
    return wg.perspective_matrix(fov, 1.0, near, far) @ world_to_eye


def evaluated_points(ob, names):
    dg = bpy.context.evaluated_depsgraph_get()
    dg.update()
    me = ob.evaluated_get(dg).data
    n = len(me.vertices)
    out = {}
    for name in names:
        buf = np.zeros(n * 3, dtype=np.float32)
        me.attributes[name].data.foreach_get("vector", buf)
        out[name] = buf.reshape(-1, 3).astype(np.float64)
    return out


def expected_texels(ob, points_local, matrix, size):
    w = np.array(ob.matrix_world)
    world = points_local @ w[:3, :3].T + w[:3, 3]
    h = np.c_[world, np.ones(len(world))] @ np.asarray(matrix).T
    ndc = h[:, :2] / h[:, 3:]
    return (ndc * 0.5 + 0.5) * np.asarray(size, dtype=np.float64), h


def test_texel_attribute_equals_numpy_per_vertex(scene, nodes, wg):
    ground = scene.objects["lixel_nodes ground"]
    ground.location = (0.4, -0.2, 0.3)
    ground.rotation_euler = (0.1, -0.2, 0.7)
    ground.scale = (1.3, 0.8, 1.0)
    m0 = perspective_light(wg, (2.0, -3.0, 12.0), (0.0, 0.0, 0.0))
    m1 = wg.ortho_matrix(-6, 6, -5, 5, 1, 40) @ wg.look_along(
        np.array([3.0, 3.0, 10.0]), np.array([-0.3, -0.3, -1.0]), np.array([0.0, 1.0, 0.0]))
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(m0, (1024, 512)), _Map(m1, (300, 200))))
    mod = nodes.add_texel_grid(ground, carrier, map_index=0)
    got = evaluated_points(ground, ["position", nodes.TEXEL_ATTRIBUTE, nodes.XYW_ATTRIBUTE, nodes.SIZE_ATTRIBUTE])
    expect, h = expected_texels(ground, got["position"], m0, (1024, 512))
    assert np.all(h[:, 3] > 0)
    # float32 attributes: a texel coordinate of ~1000 is good to ~1e-4
    np.testing.assert_allclose(got[nodes.TEXEL_ATTRIBUTE][:, :2], expect, atol=2e-3)
    np.testing.assert_allclose(got[nodes.XYW_ATTRIBUTE], h[:, [0, 1, 3]], rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(got[nodes.SIZE_ATTRIBUTE][:, :2], np.broadcast_to([1024, 512], (len(h), 2)))
    # the second map, through the modifier's Map Index
    nodes.add_texel_grid(ground, carrier, map_index=1)
    got = evaluated_points(ground, ["position", nodes.TEXEL_ATTRIBUTE])
    expect, _ = expected_texels(ground, got["position"], m1, (300, 200))
    np.testing.assert_allclose(got[nodes.TEXEL_ATTRIBUTE][:, :2], expect, atol=2e-3)
    # the group follows the carrier when the matrices change
    m2 = perspective_light(wg, (-4.0, 1.0, 9.0), (0.5, 0.0, 0.0), fov=math.radians(70))
    nodes.ensure_carrier(scene, _Setup(_Map(m0, (64, 64)), _Map(m2, (2048, 2048))))
    got = evaluated_points(ground, ["position", nodes.TEXEL_ATTRIBUTE])
    expect, _ = expected_texels(ground, got["position"], m2, (2048, 2048))
    np.testing.assert_allclose(got[nodes.TEXEL_ATTRIBUTE][:, :2], expect, atol=5e-3)
    # the material is assigned by the modifier
    dg = bpy.context.evaluated_depsgraph_get()
    assert nodes.TEXEL_MATERIAL in [mat.name for mat in ground.evaluated_get(dg).data.materials if mat]
    assert mod.node_group.name == nodes.TEXEL_GROUP


def test_divide_is_by_signed_w(scene, nodes, wg):
    """Points behind the light (w < 0) must not be mirrored as Project Point's |w| would."""
    ground = scene.objects["lixel_nodes ground"]
    m = perspective_light(wg, (0.0, 0.0, 0.2), (0.0, 0.0, 5.0), fov=math.radians(120), near=0.05)
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(m, (100, 100))))
    nodes.add_texel_grid(ground, carrier)
    got = evaluated_points(ground, ["position", nodes.TEXEL_ATTRIBUTE])
    expect, h = expected_texels(ground, got["position"], m, (100, 100))
    assert np.all(h[:, 3] < 0)
    np.testing.assert_allclose(got[nodes.TEXEL_ATTRIBUTE][:, :2], expect, rtol=1e-4, atol=1e-3)


def test_frustum_from_matrix_is_the_inverse_projected_cube(scene, nodes, wg):
    m0 = perspective_light(wg, (1.0, 2.0, 9.0), (0.0, 0.0, 0.0))
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(m0, (512, 512))))
    ob = nodes.add_frustum_object(scene, carrier, 0)
    ob.location = (1.0, -2.0, 0.5)  # the group outputs in the object's local space
    for matrix in (m0, perspective_light(wg, (-3.0, 1.0, 7.0), (1.0, 0.0, 0.0), fov=math.radians(30))):
        nodes.ensure_carrier(scene, _Setup(_Map(matrix, (512, 512))))
        got = evaluated_points(ob, ["position"])["position"]
        world = got + np.array(ob.location)
        expect = wg.clip_volume_corners(matrix)
        assert len(world) == 8
        d = np.linalg.norm(world[:, None] - expect[None], axis=2)
        scale = np.linalg.norm(expect.max(axis=0) - expect.min(axis=0))
        assert d.min(axis=1).max() < 1e-5 * scale
        assert sorted(d.argmin(axis=1)) == list(range(8))


def test_frustum_from_matrix_draws_no_mirrored_box_for_a_volume_through_infinity(scene, nodes, wg):
    """A clip volume with a corner at w < 0 is not the hexahedron of its divided corners: nothing is drawn."""
    through_infinity = np.random.default_rng(2).normal(size=(4, 4))
    assert np.sum(wg.clip_volume_corners_h(through_infinity)[:, 3] < 0) == 1
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(through_infinity, (512, 512))))
    ob = nodes.add_frustum_object(scene, carrier, 0)
    assert len(evaluated_points(ob, ["position"])["position"]) == 0
    nodes.ensure_carrier(scene, _Setup(_Map(perspective_light(wg, (1.0, 2.0, 9.0), (0.0, 0.0, 0.0)), (512, 512))))
    assert len(evaluated_points(ob, ["position"])["position"]) == 8                # a bounded one is drawn again


def test_a_corner_at_a_tiny_positive_w_is_through_infinity_as_for_the_overlays(scene, nodes, wg):
    """One rule for the frustum object and the overlays (``geometry.finite_clip_volume_corners``): a corner whose w
    is positive but below the relative epsilon is at infinity, so no box reaching 1e14 is drawn. Its w survives
    float32 (the carrier's precision), so the group's own w <= 0 test does not see it."""
    s, c = 1e8, 1.0 - 2.0 ** -20            # unprojected corners (s x, s y, s z, c z + 1): w = 2^-20 at z = -1
    inverse = np.diag([s, s, s, 1.0])
    inverse[3, 2] = c
    matrix = np.linalg.inv(inverse)
    h = wg.clip_volume_corners_h(matrix)
    assert h[:, 3].min() > 0 and wg.finite_clip_volume_corners(matrix) is None
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(matrix, (512, 512))))
    ob = nodes.add_frustum_object(scene, carrier, 0)
    assert len(evaluated_points(ob, ["position"])["position"]) == 0


def test_a_volume_bounded_in_float64_but_not_in_float32_is_said_to_be_empty(scene, nodes, wg, lixel):
    """The rule says bounded (w = 2^-24 at |x, y, z| = 100 is above its relative epsilon), but the group's float32
    inverse puts that corner at w <= 0 and draws nothing: Add Frustum's note says so, and why."""
    frustum_note = importlib.import_module(f"{lixel.__name__}.addon.ui.operators.bake").frustum_note
    s, c = 100.0, 1.0 - 2.0 ** -24
    inverse = np.diag([s, s, s, 1.0])
    inverse[3, 2] = c
    matrix = np.linalg.inv(inverse)
    assert wg.finite_clip_volume_corners(matrix) is not None
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(matrix, (512, 512))))
    ob = nodes.add_frustum_object(scene, carrier, 0)
    assert len(evaluated_points(ob, ["position"])["position"]) == 0
    dg = bpy.context.evaluated_depsgraph_get()
    assert "empty for now: a corner of this map's volume lies so near infinity" in frustum_note(ob, matrix, dg)
    bounded = perspective_light(wg, (1.0, 2.0, 9.0), (0.0, 0.0, 0.0))
    nodes.ensure_carrier(scene, _Setup(_Map(bounded, (512, 512))))
    assert frustum_note(ob, bounded, bpy.context.evaluated_depsgraph_get()) == ""


def test_add_frustum_says_when_its_map_reaches_through_infinity(lixel, nodes, wg, capfd):
    """A point light behind the camera: a split of the cascade warps its map through infinity. The operator says its
    object is empty exactly where the group draws nothing, and says nothing of the kind for a bounded map."""
    from mathutils import Matrix
    with active_scene("lixel_frustum_note", mesh=False) as sc:
        for name, lo, hi in (("ground", (-50, -50, -0.1), (50, 50, 0)), ("post", (0, 0, 0), (1, 1, 3))):
            me = bpy.data.meshes.new(name)
            me.from_pydata([(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], [],
                           [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
            sc.collection.objects.link(bpy.data.objects.new(name, me))
        sc.camera.matrix_world = Matrix(((1, 0, 0, 0), (0, 0.14834, -0.988936, -10), (0, 0.988936, 0.14834, 2),
                                         (0, 0, 0, 1)))
        sc.camera.data.sensor_fit, sc.camera.data.angle_y = "VERTICAL", math.radians(60)
        sc.camera.data.clip_start, sc.camera.data.clip_end = 0.1, 70.0
        light = sc.objects["lixel_frustum_note light"]
        light.data.type, light.location = "POINT", (-3.0, -12.0, 3.0)
        sc.lixel.initialised, sc.lixel.method = True, "cascade"
        try:
            assert bpy.ops.lixel.refresh() == {"FINISHED"}
            live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
            unbounded = [wg.finite_clip_volume_corners(m.matrix) is None for m in live.state(sc).setup.maps]
            assert True in unbounded and False in unbounded
            for i in (unbounded.index(True), unbounded.index(False)):
                capfd.readouterr()
                assert bpy.ops.lixel.frustum_add(map_index=i) == {"FINISHED"}
                said = capfd.readouterr().out
                ob = bpy.data.objects[f"Lixel Frustum (map {i})"]
                assert ("empty for now: this map's volume reaches through infinity" in said) == unbounded[i], said
                assert len(evaluated_points(ob, ["position"])["position"]) == (0 if unbounded[i] else 8)
        finally:
            made = importlib.import_module(f"{lixel.__name__}.addon.scene.owned").MADE_KEY
            for data in (bpy.data.objects, bpy.data.meshes, bpy.data.collections, bpy.data.node_groups):
                for idb in [i for i in data if made in i.keys()]:
                    data.remove(idb)
            live.clear()


def test_a_frustum_of_a_map_the_carrier_does_not_hold_draws_nothing(scene, nodes, wg):
    """A frustum object added for map 2 of a 3-map setup, then the setup synced with 1 map: its group sampled a zero
    matrix and drew a 2-unit cube at the origin, a box of no map. Now it draws nothing, and draws the volume again
    when the carrier holds its map once more. A group saved at version 3 is rebuilt in place (its modifiers keep
    it) the next time Lixel builds it."""
    maps = [_Map(perspective_light(wg, (1.0 + i, 2.0, 9.0), (0.0, 0.0, 0.0)), (512, 512)) for i in range(3)]
    carrier = nodes.ensure_carrier(scene, _Setup(*maps))
    ob = nodes.add_frustum_object(scene, carrier, 2)
    assert len(evaluated_points(ob, ["position"])["position"]) == 8
    nodes.ensure_carrier(scene, _Setup(maps[0]))
    assert nodes.followers_of_missing_maps(carrier, 1) == [(ob.name, 2)]
    assert len(evaluated_points(ob, ["position"])["position"]) == 0
    nodes.ensure_carrier(scene, _Setup(*maps))
    world = evaluated_points(ob, ["position"])["position"] + np.array(ob.location)
    assert len(world) == 8 and np.abs(np.sort(world, axis=0) - np.sort(wg.clip_volume_corners(maps[2].matrix),
                                                                       axis=0)).max() < 1e-4
    group = ob.modifiers[nodes.FRUSTUM_MODIFIER].node_group
    group[nodes.VERSION_KEY] = 3                        # as a file saved before this version holds it
    assert nodes.ensure_frustum_group() == group and group[nodes.VERSION_KEY] == nodes.FRUSTUM_GROUP_VERSION
    assert ob.modifiers[nodes.FRUSTUM_MODIFIER].node_group == group
    nodes.ensure_carrier(scene, _Setup(maps[0]))
    assert len(evaluated_points(ob, ["position"])["position"]) == 0


def test_groups_are_idempotent_and_versioned(scene, nodes):
    g1 = nodes.ensure_texel_grid_group()
    n_nodes = len(g1.nodes)
    assert nodes.ensure_texel_grid_group() == g1 and len(g1.nodes) == n_nodes
    assert g1[nodes.VERSION_KEY] == nodes.TEXEL_GROUP_VERSION
    ground = scene.objects["lixel_nodes ground"]
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(np.eye(4), (8, 8))))
    mod = nodes.add_texel_grid(ground, carrier)
    nodes.add_texel_grid(ground, carrier)
    assert len(ground.modifiers) == 1
    assert not any(s.material and s.material.name == nodes.TEXEL_MATERIAL for s in ground.material_slots)
    # an outdated group still as Lixel built it is rebuilt in place: the modifier keeps using it
    g1[nodes.VERSION_KEY] = 0
    said = []
    g2 = nodes.ensure_texel_grid_group(said)
    assert g2 == g1 and mod.node_group == g2 and len(g2.nodes) == n_nodes and said == []
    assert g2[nodes.VERSION_KEY] == nodes.TEXEL_GROUP_VERSION
    f1 = nodes.ensure_frustum_group()
    assert nodes.ensure_frustum_group() == f1
    n_groups = len(bpy.data.node_groups)
    nodes.ensure_frustum_group()
    nodes.ensure_texel_grid_group()
    assert len(bpy.data.node_groups) == n_groups
    m1 = nodes.ensure_texel_material()
    assert nodes.ensure_texel_material() == m1


def test_an_edited_group_is_never_rebuilt(scene, nodes, wg, tmp_path):
    """A user edits Lixel's frustum group without renaming it (the cube's size 2 -> 3, a node muted), and Lixel's
    next version rebuilds it: the edits were lost. Now an outdated group that differs from the fingerprint Lixel
    stored when it built it is left as it is, the user's (Lixel's marks off, a fake user so it is saved though
    unused); the new version is built beside it, Lixel's modifiers follow that, and the message names both groups
    and the objects moved. The fingerprint survives a save and load (no false alarm), and an unedited outdated group
    is still rebuilt in place."""
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(perspective_light(wg, (1.0, 2.0, 9.0), (0.0, 0.0, 0.0)),
                                                      (512, 512))))
    ob = nodes.add_frustum_object(scene, carrier, 0)
    group = ob.modifiers[nodes.FRUSTUM_MODIFIER].node_group
    with saved_and_loaded(group, "node_groups", tmp_path / "group.blend") as loaded:
        assert loaded is not group and loaded[nodes.FINGERPRINT_KEY] == nodes.fingerprint(loaded)
    cube = next(n for n in group.nodes if n.bl_idname == "GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (3.0, 3.0, 3.0)           # the user's edit
    group.nodes[-1].mute = True
    group[nodes.VERSION_KEY] = nodes.FRUSTUM_GROUP_VERSION - 1    # as a file from before Lixel's next version
    edited = nodes.fingerprint(group)
    said = []
    other = nodes.add_frustum_object(scene, carrier, 0, said)
    new = other.modifiers[nodes.FRUSTUM_MODIFIER].node_group
    try:
        assert other == ob and new != group and new.name == f"{nodes.FRUSTUM_GROUP}.001"
        assert nodes.fingerprint(group) == edited and tuple(cube.inputs["Size"].default_value) == (3.0, 3.0, 3.0)
        assert group.use_fake_user and not any(k.startswith("lixel") for k in group.keys())
        assert new[nodes.VERSION_KEY] == nodes.FRUSTUM_GROUP_VERSION and nodes.ensure_frustum_group() == new
        assert said == [f"Lixel: node group '{group.name}' (version {nodes.FRUSTUM_GROUP_VERSION - 1}) is not as "
                        f"Lixel built it (edited, or made before Lixel kept a fingerprint), so it was left as it is, "
                        f"yours now (with a fake user, so it is saved); Lixel's version {nodes.FRUSTUM_GROUP_VERSION} "
                        f"is '{new.name}', now used by Lixel's modifiers on '{ob.name}': to keep your edits, point "
                        f"those modifiers back to '{group.name}' or copy them into '{new.name}'"]
        assert len(evaluated_points(ob, ["position"])["position"]) == 8      # the map's volume, from the new group
    finally:
        bpy.data.node_groups.remove(group)


def test_an_edited_texel_material_is_never_rebuilt(scene, nodes, tmp_path):
    """The "Lixel Texel Grid" material had a version but no fingerprint: a user who changed its colours (without
    renaming it) lost them to Lixel's next version, which emptied and rebuilt its nodes in place. Now it keeps a
    fingerprint as the node groups do: an outdated material that differs from it is left as it is, the user's
    (Lixel's marks off, a fake user); the new version is built beside it and Lixel's texel grids (their modifier's
    Material and the slot Lixel added) follow it, said by name. The fingerprint survives a save and load, and an
    unedited outdated material is still rebuilt in place."""
    ground = scene.objects["lixel_nodes ground"]
    carrier = nodes.ensure_carrier(scene, _Setup(_Map(np.eye(4), (8, 8))))
    mod = nodes.add_texel_grid(ground, carrier)
    key = nodes._input(mod.node_group, "Material")
    mat = mod[key]
    with saved_and_loaded(mat, "materials", tmp_path / "material.blend") as loaded:
        assert loaded is not mat and loaded[nodes.FINGERPRINT_KEY] == nodes.fingerprint(loaded.node_tree)
    mix = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeMix")
    mix.inputs[6].default_value = (1.0, 0.0, 0.0, 1.0)                  # the user's colour
    mat[nodes.VERSION_KEY] = nodes.MATERIAL_VERSION - 1                 # as a file from before Lixel's next version
    ground.data.materials.append(mat)                                   # the slot Lixel added before session 21
    edited = nodes.fingerprint(mat.node_tree)
    said = []
    nodes.add_texel_grid(ground, carrier, 0, said)
    new = mod[key]
    try:
        assert new != mat and new.name == f"{nodes.TEXEL_MATERIAL}.001"
        assert nodes.fingerprint(mat.node_tree) == edited and tuple(mix.inputs[6].default_value) == (1, 0, 0, 1)
        assert mat.use_fake_user and not any(k.startswith("lixel") for k in mat.keys())
        assert new[nodes.VERSION_KEY] == nodes.MATERIAL_VERSION and nodes.ensure_texel_material() == new
        assert [s.material for s in ground.material_slots].count(new) == 1
        assert mat not in [s.material for s in ground.material_slots]
        assert said == [f"Lixel: material '{mat.name}' (version {nodes.MATERIAL_VERSION - 1}) is not as Lixel built "
                        f"it (edited, or made before Lixel kept a fingerprint), so it was left as it is, yours now "
                        f"(with a fake user, so it is saved); Lixel's version {nodes.MATERIAL_VERSION} is "
                        f"'{new.name}', now used by Lixel's modifiers on '{ground.name}': to keep your edits, point "
                        f"those modifiers back to '{mat.name}' or copy them into '{new.name}'"]
        new[nodes.VERSION_KEY] = nodes.MATERIAL_VERSION - 1               # unedited: rebuilt in place
        assert nodes.ensure_texel_material(said) == new and len(said) == 1
    finally:
        nodes.remove_texel_grid(ground)
        bpy.data.materials.remove(mat)
        bpy.data.materials.remove(new)      # the next test makes Lixel's under its own name again


FINGERPRINT_CHILD = r'''
import importlib, importlib.util, sys
import bpy
conftest, path = sys.argv[1:3]
spec = importlib.util.spec_from_file_location("bconf", conftest)
bconf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bconf)
bconf.enable_lixel()
nodes = importlib.import_module(bconf.ADDON_MODULE + ".addon.ui.nodes")
with bpy.data.libraries.load(path) as (names, into):
    into.node_groups = list(names.node_groups)
for group in into.node_groups:
    print("LIXEL_FINGERPRINT", group[nodes.FINGERPRINT_KEY] == nodes.fingerprint(group))
bconf.disable_lixel()
'''


def test_the_groups_lixel_built_read_as_unedited_in_another_process(nodes, tmp_path):
    """A fingerprint that changed from one Blender session to the next (a set's order, an address) would make every
    group Lixel built look edited after the file is opened again: it is the same in a fresh process with another
    hash seed."""
    import os
    import subprocess
    import sys
    from pathlib import Path
    path = tmp_path / "groups.blend"
    bpy.data.libraries.write(str(path), {nodes.ensure_texel_grid_group(), nodes.ensure_frustum_group()})
    script = tmp_path / "fingerprint.py"
    script.write_text(FINGERPRINT_CHILD)
    conftest = Path(__file__).with_name("conftest.py")
    proc = subprocess.run([sys.executable, str(script), str(conftest), str(path)], capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONHASHSEED": "12345"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    said = [line.split()[1] for line in proc.stdout.splitlines() if line.startswith("LIXEL_FINGERPRINT")]
    assert said == ["True", "True"], proc.stdout[-2000:]


def test_a_texel_grid_of_a_map_the_carrier_does_not_hold_leaves_the_mesh_as_it_is(scene, nodes, wg):
    """A texel grid added for map 2 of a 3-map setup, then the setup synced with 1 map: its group sampled a default
    matrix and coloured the mesh by texels of no map. Now it passes the mesh through as it is (no texel attributes),
    and shows map 2's texels again when the carrier holds it once more."""
    ground = scene.objects["lixel_nodes ground"]
    maps = [_Map(perspective_light(wg, (1.0 + i, 2.0, 9.0), (0.0, 0.0, 0.0)), (64, 64)) for i in range(3)]
    carrier = nodes.ensure_carrier(scene, _Setup(*maps))
    nodes.add_texel_grid(ground, carrier, map_index=2)
    try:
        local = np.array([v.co for v in ground.data.vertices], dtype=np.float64)
        texels, _ = expected_texels(ground, local, maps[2].matrix, (64, 64))
        assert np.abs(evaluated_points(ground, [nodes.TEXEL_ATTRIBUTE])[nodes.TEXEL_ATTRIBUTE][:, :2] - texels).max() < 1e-2
        nodes.ensure_carrier(scene, _Setup(maps[0]))
        assert nodes.followers_of_missing_maps(carrier, 1) == [(ground.name, 2)]
        dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        me = ground.evaluated_get(dg).data
        assert nodes.TEXEL_ATTRIBUTE not in me.attributes and nodes.XYW_ATTRIBUTE not in me.attributes
        assert len(me.vertices) == len(ground.data.vertices)
        nodes.ensure_carrier(scene, _Setup(*maps))
        assert np.abs(evaluated_points(ground, [nodes.TEXEL_ATTRIBUTE])[nodes.TEXEL_ATTRIBUTE][:, :2] - texels).max() < 1e-2
    finally:
        nodes.remove_texel_grid(ground)


EEVEE = "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


@pytest.mark.parametrize("engine", ["BLENDER_WORKBENCH", "CYCLES", EEVEE])
def test_texels_show_in_renders(scene, nodes, wg, engine, tmp_path, load_pixels):
    """A 4x4-texel map over the 10 m ground, seen from straight above by an
    orthographic camera framing the ground: the render is a 4x4 checker.
    (EEVEE's first render compiles its shaders: 5-30 s on llvmpipe.)"""
    ground = scene.objects["lixel_nodes ground"]
    scene.objects["lixel_nodes cube"].hide_render = True
    cam = scene.camera
    cam.location, cam.rotation_euler = (0.0, 0.0, 12.0), (0.0, 0.0, 0.0)
    cam.data.type, cam.data.ortho_scale = "ORTHO", 10.0
    m = wg.ortho_matrix(-5, 5, -5, 5, 1, 30) @ wg.look_along(np.array([0, 0, 15.0]), np.array([0, 0, -1.0]),
                                                             np.array([0, 1.0, 0]))
    nodes.add_texel_grid(ground, nodes.ensure_carrier(scene, _Setup(_Map(m, (4, 4)))))
    world = bpy.data.worlds.new("lixel_nodes_world")
    world.color = (1.0, 1.0, 1.0)
    scene.world = world
    r = scene.render
    r.engine, r.resolution_x, r.resolution_y, r.resolution_percentage = engine, 32, 32, 100
    r.filepath = str(tmp_path / "texels.png")
    scene.view_settings.view_transform = "Standard"
    if engine != "BLENDER_WORKBENCH":
        if engine == "CYCLES":
            scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 4, False, "CPU"
        else:
            scene.eevee.taa_render_samples = 1
        if bpy.app.version < (5, 0, 0):
            world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    else:
        scene.display.shading.color_type = "VERTEX"  # "Attribute" in the UI
        scene.display.shading.light = "FLAT"
    try:
        bpy.ops.render.render(write_still=True, scene=scene.name)
        px = load_pixels(r.filepath)
    finally:
        scene.world = None
        bpy.data.worlds.remove(world)
    lum = px[..., :3].mean(axis=2)
    cells = np.array([[lum[8 * j + 3:8 * j + 5, 8 * i + 3:8 * i + 5].mean() for i in range(4)] for j in range(4)])
    parity = (np.add.outer(np.arange(4), np.arange(4)) % 2).astype(bool)
    a, b = cells[parity], cells[~parity]
    hi, lo = (a, b) if a.mean() > b.mean() else (b, a)
    assert hi.min() - lo.max() > 0.1, cells  # every light cell is lighter than every dark one
