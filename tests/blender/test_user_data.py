"""Lixel never writes into a datablock it did not make. Every datablock Lixel
makes is marked (addon/scene/owned.py); when a user's datablock already has the
name Lixel wants, Lixel's gets Blender's next free name and the user's is left
exactly as it was. Checked for every operator that makes data."""
import importlib

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene, digest

LIXEL_NAMES = ("Lixel B", "Lixel View Frustum", "Lixel Light Frustum 0 (main)", "Lixel Light Matrices",
               "Lixel Frustum (map 0)")
"""Object and mesh names Lixel's operators make (with the default lispsm setup)."""


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    m.nodes = importlib.import_module(f"{lixel.__name__}.addon.ui.nodes")
    m.live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    m.owned = importlib.import_module(f"{lixel.__name__}.addon.scene.owned")
    return m


def _sphere(name, n=114):
    """A mesh of n vertices on a sphere (the audit's 114-vertex user mesh)."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(p) for p in v], [], [(i, i + 1, i + 2) for i in range(0, n - 2, 3)])
    return me


def _geometry_node_group(name):
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    a, b = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    tree.nodes.new("GeometryNodeMeshCube").name = "user's cube"
    tree.links.new(a.outputs[0], b.inputs[0])
    return tree


@pytest.fixture
def user_scene(lixel, mods):
    """A scene whose user owns a datablock under every name Lixel uses."""
    with active_scene("lixel_user_data") as scene:
        made = []
        for name in LIXEL_NAMES:
            me = _sphere(name)
            ob = bpy.data.objects.new(name, me)
            scene.collection.objects.link(ob)
            made += [me, ob]
        coll = bpy.data.collections.new(mods.nodes.DEBUG_COLLECTION)
        scene.collection.children.link(coll)
        keep = bpy.data.objects.new("my keepsake", _sphere("my keepsake", 30))
        coll.objects.link(keep)
        made += [coll, keep, keep.data]
        made.append(_geometry_node_group(mods.nodes.TEXEL_GROUP))
        made.append(_geometry_node_group(mods.nodes.FRUSTUM_GROUP))
        mat = bpy.data.materials.new(mods.nodes.TEXEL_MATERIAL)
        mat.diffuse_color = (0.1, 0.2, 0.3, 1.0)
        made.append(mat)
        text = bpy.data.texts.new("Lixel Comparison")
        text.write("my notes, not Lixel's\n")
        made.append(text)
        img = bpy.data.images.new("Lixel Comparison", 7, 5)
        img.pixels.foreach_set(np.linspace(0, 1, 7 * 5 * 4, dtype=np.float32))
        made.append(img)
        # a user's own modifier with the texel grid's name on the mesh that gets the grid
        ground = scene.objects["lixel_user_data ground"]
        ground.modifiers.new(mods.nodes.TEXEL_MODIFIER, "SUBSURF")
        scene.lixel.initialised = True
        bpy.context.view_layer.update()
        yield scene, made
        _remove_lixel_data(mods)
        for idb in made:
            try:
                _collection_of(idb).remove(idb)
            except ReferenceError:  # already freed with the scene's objects
                pass
    mods.live.clear()


def _collection_of(idb):
    for t, name in ((bpy.types.Mesh, "meshes"), (bpy.types.Object, "objects"), (bpy.types.Collection, "collections"),
                    (bpy.types.NodeTree, "node_groups"), (bpy.types.Material, "materials"),
                    (bpy.types.Text, "texts"), (bpy.types.Image, "images")):
        if isinstance(idb, t):
            return getattr(bpy.data, name)
    raise TypeError(idb)


def _remove_lixel_data(mods):
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.collections, bpy.data.node_groups, bpy.data.materials,
                 bpy.data.texts, bpy.data.images):
        for idb in [i for i in coll if mods.owned.MADE_KEY in i.keys()]:
            coll.remove(idb)


def _select(scene, names):
    for ob in scene.objects:
        ob.select_set(ob.name in names)
    bpy.context.view_layer.objects.active = scene.objects[names[0]]


OPERATORS = [
    ("bake_debug", {}),
    ("sync_matrices", {}),
    ("frustum_add", {}),
    ("texel_grid_add", {}),
    ("compare", {"longest_side": 32}),
]


@pytest.mark.parametrize("op,kw", OPERATORS)
def test_operators_never_touch_a_users_datablock_of_their_name(user_scene, mods, op, kw):
    scene, users = user_scene
    _select(scene, ["lixel_user_data ground"])
    before = {idb.name: digest(idb) for idb in users}
    assert getattr(bpy.ops.lixel, op)(**kw) == {"FINISHED"}
    assert getattr(bpy.ops.lixel, op)(**kw) == {"FINISHED"}  # and again: Lixel finds its own by the mark
    after = {idb.name: digest(idb) for idb in users}
    changed = [n for n in before if before[n] != after.get(n)]
    assert changed == []
    mine = [i for c in (bpy.data.objects, bpy.data.meshes, bpy.data.collections, bpy.data.node_groups,
                        bpy.data.materials, bpy.data.texts, bpy.data.images) for i in c if mods.owned.is_lixel_made(i)]
    assert mine, "Lixel made nothing"
    assert not set(i.name for i in mine) & set(before), "a user's datablock was taken over"
    # made once, reused the second time: no duplicates under the same mark
    marks = [(type(i).__name__, i[mods.owned.MADE_KEY]) for i in mine if mods.owned.MADE_KEY in i.keys()]
    assert len(marks) == len(set(marks))


def test_bake_keeps_a_users_mesh_and_object_named_lixel_b(user_scene, mods):
    """The audit's case: a 114-vertex sphere named "Lixel B" was overwritten by B."""
    scene, _users = user_scene
    sphere = bpy.data.objects["Lixel B"]
    assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
    assert len(sphere.data.vertices) == 114 and sphere.data.name == "Lixel B"
    body = mods.owned.find_made(bpy.data.objects, "Lixel B")
    assert body is not None and body is not sphere and body.name.startswith("Lixel B.")
    st = mods.live.state(scene)
    assert len(body.data.vertices) == len(st.body.vertices)
    coll = mods.owned.find_made(bpy.data.collections, mods.nodes.DEBUG_COLLECTION)
    assert body.name in coll.objects and coll.name != mods.nodes.DEBUG_COLLECTION
    assert "my keepsake" in bpy.data.collections[mods.nodes.DEBUG_COLLECTION].objects


def test_a_copy_or_a_renamed_baked_object_is_the_users_and_a_rebake_leaves_it(lixel, mods):
    """Shift+D copies custom properties, Lixel's mark included: the copy a user keeps beside the baked B, and the
    baked frustum the user renames to keep, are the user's; baking again neither removes nor rewrites them."""
    with active_scene("lixel_keep_bake") as scene:
        scene.lixel.initialised = True
        try:
            assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
            body = bpy.data.objects["Lixel B"]
            copy = body.copy()
            copy.data = body.data.copy()
            body.users_collection[0].objects.link(copy)            # "Lixel B.001" beside it, as Shift+D makes
            kept = bpy.data.objects["Lixel View Frustum"]
            kept.name = "my view frustum"
            users = (copy, copy.data, kept, kept.data)
            before = [digest(idb) for idb in users]
            scene.camera.location.x += 2.0
            bpy.context.view_layer.update()
            assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
            assert [digest(idb) for idb in users] == before
            assert not mods.owned.is_lixel_made(copy) and not mods.owned.is_lixel_made(kept)
            assert mods.owned.find_made(bpy.data.objects, "Lixel View Frustum") not in (None, kept)
        finally:
            _remove_lixel_data(mods)
    mods.live.clear()


def test_the_texel_grid_is_removed_without_touching_a_users_modifier(user_scene, mods):
    scene, _users = user_scene
    ground = scene.objects["lixel_user_data ground"]
    _select(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    assert [m.type for m in ground.modifiers] == ["SUBSURF", "NODES"]
    assert ground.modifiers[0].name == mods.nodes.TEXEL_MODIFIER  # the user's keeps its name
    assert mods.owned.is_lixel_made(ground.modifiers[1].node_group)
    assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
    assert [(m.name, m.type) for m in ground.modifiers] == [(mods.nodes.TEXEL_MODIFIER, "SUBSURF")]


def test_files_from_before_the_mark_are_still_lixels(lixel, mods):
    """Debug objects and node groups saved before MADE_KEY carry their old marks."""
    with active_scene("lixel_legacy"):
        ob = bpy.data.objects.new("Lixel B", None)
        ob[mods.owned.DEBUG_KEY] = "baked:body"
        tree = bpy.data.node_groups.new(mods.nodes.TEXEL_GROUP, "GeometryNodeTree")
        tree["lixel_version"] = 0
        try:
            assert mods.owned.find_made(bpy.data.objects, "Lixel B") is ob
            assert mods.owned.find_made(bpy.data.node_groups, mods.nodes.TEXEL_GROUP) is tree
        finally:
            bpy.data.objects.remove(ob)
            bpy.data.node_groups.remove(tree)


def test_the_texel_grids_of_many_objects_go_at_once(user_scene, mods):
    """Removing the grids of many selected objects at once (the operator asks which meshes still show a grid once,
    not once per object: per object it took 92 s for 8,000 tiles) takes off what Lixel added to a mesh only when
    none of its objects keeps a grid, whichever of them were selected."""
    scene, _users = user_scene
    cube, ground = scene.objects["lixel_user_data cube"], scene.objects["lixel_user_data ground"]
    twins = [bpy.data.objects.new(f"my twin {i}", cube.data) for i in range(2)]
    for twin in twins:
        scene.collection.objects.link(twin)
    try:
        _select(scene, [cube.name, ground.name, *(t.name for t in twins)])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        _select(scene, [cube.name, ground.name, twins[0].name])
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert [mods.nodes.lixel_modifier(ob, mods.nodes.TEXEL_MODIFIER) is None
                for ob in (cube, ground, *twins)] == [True, True, True, False]
        assert cube.data.attributes.active_color_name == mods.nodes.PARITY_COLOR_ATTRIBUTE   # twin 1 shows it
        assert ground.data.attributes.active_color_name == ""
        assert mods.nodes.remove_texel_grids([twins[1], ground]) == 1
        assert cube.data.attributes.active_color_name == ""
    finally:
        for twin in twins:
            bpy.data.objects.remove(twin)


def test_the_texel_grid_leaves_the_materials_of_a_shared_mesh_alone(user_scene, mods):
    """A mesh with no material, shared by two objects (Alt+D): the texel grid added to one put Lixel's material in
    the mesh's first slot, which every face uses, so the other object, never selected, rendered with Lixel's texel
    material (without the grid's attributes: the texels of no map). The grid's group sets its material itself (Set
    Material; the modifier keeps it saved), so Lixel adds no slot to a mesh: the twin is left exactly as it was, in
    its data and as evaluated, and the gridded object still shows Lixel's material."""
    scene, _users = user_scene
    cube = scene.objects["lixel_user_data cube"]
    mesh = cube.data
    assert len(mesh.materials) == 0
    twin = bpy.data.objects.new("my twin", mesh)
    scene.collection.objects.link(twin)
    try:
        before = (digest(twin), digest(mesh))
        _select(scene, [cube.name])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        grid_material = mods.owned.find_made(bpy.data.materials, mods.nodes.TEXEL_MATERIAL)
        dg = bpy.context.evaluated_depsgraph_get()
        assert [m for m in twin.evaluated_get(dg).data.materials if m] == []
        assert grid_material.name in [m.name for m in cube.evaluated_get(dg).data.materials if m]
        assert len(mesh.materials) == 0 and digest(twin) == before[0]
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert (digest(twin), digest(mesh)) == before
    finally:
        bpy.data.objects.remove(twin)


def test_the_texel_grid_on_a_shared_mesh_leaves_with_its_last_object(user_scene, mods):
    """Two objects share a mesh that has the user's material: removing the grid from one leaves the other's
    grid whole (the colour attribute Workbench shows stays on the mesh); removing it from the last takes off only
    what Lixel added."""
    scene, _users = user_scene
    cube = scene.objects["lixel_user_data cube"]
    mesh = cube.data
    paint = bpy.data.materials.new("my paint")
    mesh.materials.append(paint)
    twin = bpy.data.objects.new("my twin", mesh)
    scene.collection.objects.link(twin)
    try:
        _select(scene, [cube.name, twin.name])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        with_grid = ([m.name for m in mesh.materials], mesh.attributes.active_color_name)
        grid_material = mods.owned.find_made(bpy.data.materials, mods.nodes.TEXEL_MATERIAL)
        assert grid_material is not None and with_grid == (["my paint"], mods.nodes.PARITY_COLOR_ATTRIBUTE)
        _select(scene, [cube.name])
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert mods.nodes.lixel_modifier(cube, mods.nodes.TEXEL_MODIFIER) is None
        assert mods.nodes.lixel_modifier(twin, mods.nodes.TEXEL_MODIFIER) is not None
        assert ([m.name for m in mesh.materials], mesh.attributes.active_color_name) == with_grid
        _select(scene, [twin.name])
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert [m for m in mesh.materials] == [paint]
        assert (mesh.attributes.active_color_name, mesh.attributes.default_color_name) == ("", "")
    finally:
        bpy.data.objects.remove(twin)
        bpy.data.materials.remove(paint)
