"""Every LIXEL_OT_* operator runs in background mode on a sample scene, and each
one that needs a setup reports a clear error (and changes nothing) when the
camera, the light or the meshes are missing."""
import importlib
import json
import os
import re

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene, look_at, remove_scene


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    for name in ("live", "nodes", "properties", "overlays"):
        setattr(m, name, importlib.import_module(f"{lixel.__name__}.addon.ui.{name}"))
    m.warp = importlib.import_module(f"{lixel.__name__}.addon.warp")
    m.describe = importlib.import_module(f"{lixel.__name__}.addon.scene.describe")
    m.cli = importlib.import_module(f"{lixel.__name__}.addon.cli")
    m.owned = importlib.import_module(f"{lixel.__name__}.addon.scene.owned")
    return m


@pytest.fixture
def scene(lixel):
    with active_scene("lixel_ops") as sc:
        yield sc
    for name in ("Lixel Debug",):
        coll = bpy.data.collections.get(name)
        if coll is not None:
            for ob in list(coll.objects):
                bpy.data.objects.remove(ob)
            bpy.data.collections.remove(coll)


def _select_only(scene, names):
    for ob in scene.objects:
        ob.select_set(ob.name in names)
    bpy.context.view_layer.objects.active = scene.objects[names[0]] if names else None


def test_refresh_computes_the_scene_setup(scene, mods):
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    st = mods.live.state(scene)
    assert st.ok and len(st.setup.maps) >= 1
    # the same setup as the warp core gives for the described scene
    view, light, bounds = mods.describe.describe_scene(bpy.context)
    expect = mods.warp.compute(st.method_used, view, light, bounds, scene.lixel.to_settings().warp)
    for a, b in zip(st.setup.maps, expect.maps):
        np.testing.assert_allclose(a.matrix, b.matrix, rtol=1e-12, atol=1e-12)
    assert scene.lixel.initialised


def test_toggle_every_overlay_adds_and_removes_draw_handlers(scene, mods):
    for name, _label, _desc in mods.properties.OVERLAYS:
        assert bpy.ops.lixel.toggle_overlay(overlay=name) == {"FINISHED"}
        assert getattr(scene.lixel, name)
        assert mods.overlays.draw_handlers_active() == ("pixel", "view")
        assert bpy.ops.lixel.toggle_overlay(overlay=name) == {"FINISHED"}
        assert not getattr(scene.lixel, name)
        assert mods.overlays.draw_handlers_active() == ()


def test_bake_is_idempotent_and_matches_the_setup(scene, mods):
    assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
    coll = bpy.data.collections["Lixel Debug"]
    first = sorted(ob.name for ob in coll.objects)
    n_objects, n_meshes = len(bpy.data.objects), len(bpy.data.meshes)
    assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
    assert sorted(ob.name for ob in coll.objects) == first
    assert (len(bpy.data.objects), len(bpy.data.meshes)) == (n_objects, n_meshes)
    st = mods.live.state(scene)
    body = coll.objects["Lixel B"].data
    co = np.array([v.co for v in body.vertices], dtype=np.float64)
    assert len(co) == len(st.body.vertices)
    d = np.linalg.norm(co[:, None] - st.body.vertices[None], axis=2)
    assert d.min(axis=1).max() < 1e-5 * st.body.scale + 1e-6
    assert len(body.polygons) == len(st.body.faces)
    # baked objects are never casters or receivers (B must not feed back into itself)
    bounds_before = st.bounds
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    np.testing.assert_array_equal(mods.live.state(scene).bounds.receivers, bounds_before.receivers)


def test_export_writes_the_cli_format(scene, mods, tmp_path):
    path = tmp_path / "setup.json"
    assert bpy.ops.lixel.export_json(filepath=str(path)) == {"FINISHED"}
    doc = json.loads(path.read_text())
    st = mods.live.state(scene)
    assert set(doc) == {"maps", "diagnostics"}
    assert doc == json.loads(json.dumps(mods.cli.setup_json(st.setup)))
    path_all = tmp_path / "all.json"
    assert bpy.ops.lixel.export_json(filepath=str(path_all), all_methods=True) == {"FINISHED"}
    doc = json.loads(path_all.read_text())
    assert set(doc["methods"]) == set(mods.warp.METHODS)


def test_export_never_overwrites_a_file_without_the_json_extension(scene, tmp_path):
    """From Python there is no file browser to add ".json": a path such as the .blend file's own was opened and
    overwritten. It gets the extension, as Blender's exporters add theirs."""
    blend = tmp_path / "shot.blend"
    blend.write_bytes(b"BLENDER-v405 the user's work")
    assert bpy.ops.lixel.export_json(filepath=str(blend)) == {"FINISHED"}
    assert blend.read_bytes() == b"BLENDER-v405 the user's work"
    assert set(json.loads((tmp_path / "shot.blend.json").read_text())) == {"maps", "diagnostics"}


@pytest.mark.parametrize("given", ["none", "empty", "folder", "folder/"])
def test_export_without_a_file_name_is_refused(scene, tmp_path, monkeypatch, given):
    """No file name (a script's ``export_json()``, a name cleared in the file browser, a folder) wrote a hidden
    '.json' into the working or the given folder and reported success. Refused as Blender's exporters refuse it
    ("No filepath given"); nothing written."""
    monkeypatch.chdir(tmp_path)
    kw = {"none": {}, "empty": {"filepath": ""}, "folder": {"filepath": str(tmp_path)},
          "folder/": {"filepath": str(tmp_path) + os.sep}}[given]
    with pytest.raises(RuntimeError, match="Lixel: no file name given.*: name the JSON file to export to"):
        bpy.ops.lixel.export_json(**kw)
    assert list(tmp_path.iterdir()) == []


def test_export_reports_an_unwritable_path(scene, tmp_path):
    with pytest.raises(RuntimeError, match="cannot write"):
        bpy.ops.lixel.export_json(filepath=str(tmp_path / "missing_dir" / "x.json"))


def test_export_to_a_blend_relative_path_writes_beside_the_blend_file(lixel, tmp_path, recwarn):
    """"//setup.json" is Blender's way to say "beside the .blend file"; it was opened as "/setup.json", the root of
    the file system. Blender 4.5 on warns of a "//" path given to a property not marked as taking one."""
    before = tmp_path / "before.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(before), copy=True)
    (tmp_path / "project").mkdir()
    try:
        with active_scene("lixel_relative"):
            bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "project" / "shot.blend"))
            assert bpy.ops.lixel.export_json(filepath="//setup.json") == {"FINISHED"}
        assert set(json.loads((tmp_path / "project" / "setup.json").read_text())) == {"maps", "diagnostics"}
        assert not [str(w.message) for w in recwarn if "relative" in str(w.message)]
    finally:
        bpy.ops.wm.open_mainfile(filepath=str(before), load_ui=False)


def test_compare_lists_and_renders_every_method(scene, mods):
    assert bpy.ops.lixel.compare(longest_side=64) == {"FINISHED"}
    text = bpy.data.texts["Lixel Comparison"].as_string()
    for name in mods.warp.METHODS:
        assert f"\n{name} " in text
    rendered = [n for n in mods.warp.METHODS if f"\n{n} " in text and f"\n{n}  error" not in text
                and f"\n{n} error" not in text]
    img = bpy.data.images["Lixel Comparison"]
    # a grid of 64x36 pictures, each under a two-line label strip, 3 per row, 4 px apart
    label = 2 * importlib.import_module(f"{mods.live.__name__.rsplit('.', 1)[0]}.renders").LABEL_LINE + 6
    cols = min(3, len(rendered))
    rows = -(-len(rendered) // 3)
    assert tuple(img.size) == (cols * 64 + (cols - 1) * 4, rows * (36 + label) + (rows - 1) * 4)
    px = np.empty(img.size[0] * img.size[1] * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    first = px.reshape(img.size[1], img.size[0], 4)[-(36 + label):-label, :64, :3]
    assert first.std() > 0.01  # a picture of the scene, not a blank
    bpy.data.texts.remove(bpy.data.texts["Lixel Comparison"])
    bpy.data.images.remove(img)


def test_compare_from_a_3d_view_with_a_local_camera_names_that_camera(scene, mods):
    """View sidebar > View > Local Camera, with or without a scene camera: Compare runs on the view's camera and
    its text names that camera (it named the scene's, and failed as a bug where the scene has none)."""
    side = bpy.data.objects.new("lixel_ops side", bpy.data.cameras.new("lixel_ops side"))
    scene.collection.objects.link(side)
    side.location = (-6, -7, 5)
    side.rotation_euler = (-side.location).to_track_quat("-Z", "Y").to_euler()
    win = bpy.context.window
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    space, region = area.spaces.active, next(r for r in area.regions if r.type == "WINDOW")
    was = space.use_local_camera, space.camera
    try:
        space.use_local_camera, space.camera = True, side
        for scene_camera in (scene.camera, None):
            scene.camera = scene_camera
            with bpy.context.temp_override(window=win, area=area, region=region, space_data=space):
                assert bpy.ops.lixel.compare(longest_side=16) == {"FINISHED"}
            assert "camera 'lixel_ops side'" in bpy.data.texts["Lixel Comparison"].as_string().splitlines()[0]
    finally:
        space.use_local_camera, space.camera = was
        mods.live.follow(scene, None)

def test_planes_from_selected_objects_and_faces(scene):
    ground = scene.objects["lixel_ops ground"]
    ground.location.z = 0.25
    bpy.context.view_layer.update()
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    planes = scene.lixel.planes
    assert len(planes) == 1
    np.testing.assert_allclose(planes[0].normal, (0, 0, 1), atol=1e-6)
    assert planes[0].point[2] == pytest.approx(0.25)
    # edit mode: two selected faces of the ground are coplanar -> one plane; a cube side adds another
    bpy.ops.object.mode_set(mode="EDIT")
    import bmesh
    bm = bmesh.from_edit_mesh(ground.data)
    for f in bm.faces:
        f.select = f.index in (0, 1)
    bmesh.update_edit_mesh(ground.data)
    assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
    assert len(planes) == 1
    bpy.ops.object.mode_set(mode="OBJECT")
    assert bpy.ops.lixel.plane_remove(index=0) == {"FINISHED"}
    assert len(planes) == 0


def test_planes_without_selection_is_a_clear_error(scene):
    _select_only(scene, [])
    with pytest.raises(RuntimeError, match="no mesh selected"):
        bpy.ops.lixel.planes_from_selection()


def test_a_curve_a_text_and_a_collection_instance_selected_are_named_not_called_no_mesh(scene, capfd):
    """With a bevelled curve, a text and a collection instance selected (each shows a surface and casts its shadow),
    Add Texel Grid and Planes From Selection said "no mesh selected"; with a mesh too, they left them out without a
    word. They name them as what they are and how to make meshes of them."""
    curve = bpy.data.curves.new("lixel_ops curve", "CURVE")
    curve.splines.new("POLY").points.add(1)
    curve.bevel_depth = 0.2
    text = bpy.data.curves.new("lixel_ops text", "FONT")
    held = bpy.data.collections.new("lixel_ops held")
    instancer = bpy.data.objects.new("lixel_ops instancer", None)
    instancer.instance_type, instancer.instance_collection = "COLLECTION", held
    made = [bpy.data.objects.new(n, d) for n, d in (("lixel_ops curve", curve), ("lixel_ops text", text))] + [instancer]
    try:
        for ob in made:
            scene.collection.objects.link(ob)
        _select_only(scene, [ob.name for ob in made])
        named = ("'lixel_ops curve' (a curve), 'lixel_ops text' (a text), 'lixel_ops instancer' (a collection "
                 "instance) are not meshes (Object > Convert > Mesh makes meshes of curves, surfaces, metaballs and "
                 "texts; Object > Apply > Make Instances Real, of an instance's objects)")
        for op, what in ((bpy.ops.lixel.texel_grid_add, "the mesh objects that should show the texel grid"),
                         (bpy.ops.lixel.planes_from_selection, "the faces (Edit Mode) or mesh objects")):
            with pytest.raises(RuntimeError, match=re.escape(f"no mesh selected ({named}): select {what}")):
                op()
        _select_only(scene, [ob.name for ob in made] + ["lixel_ops ground"])
        capfd.readouterr()
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert bpy.ops.lixel.planes_from_selection() == {"FINISHED"}
        said = capfd.readouterr().out
        assert f"Warning: Lixel: the texel grid goes on meshes: {named}" in said
        assert f"Warning: Lixel: planes of interest come from meshes: {named}" in said
        assert [m.name for m in scene.objects["lixel_ops ground"].modifiers] == ["Lixel Texel Grid"]
    finally:
        bpy.data.batch_remove(made + [curve, text, held])


def _mesh_points(mesh) -> np.ndarray:
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def _carried_matrices(carrier, mods) -> np.ndarray:
    return np.array([np.array(d.value, dtype=np.float64) for d in
                     carrier.data.attributes[mods.nodes.MATRIX_ATTRIBUTE].data])


def _shown_debug(scene, mods, kind):
    """The Lixel debug object of ``kind`` the scene shows (in a Lixel debug collection it holds)."""
    return next(ob for coll in scene.collection.children if coll.name.startswith(mods.nodes.DEBUG_COLLECTION)
                for ob in coll.objects if ob.get(mods.owned.DEBUG_KEY) == kind)


def test_each_scene_keeps_its_own_debug_objects_and_light_matrices(lixel, mods):
    """Two shots in one file, each with its own camera: baking or syncing in the second leaves what the first
    shows (its baked B, the matrices its texel grid follows) as the first's setup made it. One shared "Lixel
    Debug" collection made the second bake rewrite the first's B, and the second sync its texel grid."""
    with active_scene("lixel_shot_a") as shot_a:
        assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        body_a, carrier_a = _shown_debug(shot_a, mods, "baked:body"), _shown_debug(shot_a, mods, "carrier")
        before = _mesh_points(body_a.data).copy(), _carried_matrices(carrier_a, mods)
        with active_scene("lixel_shot_b") as shot_b:
            shot_b.camera.location = (-8.0, 3.0, 6.0)
            look_at(shot_b.camera, (0, 0, 0))
            bpy.context.view_layer.update()
            assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
            assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
            body_b, carrier_b = _shown_debug(shot_b, mods, "baked:body"), _shown_debug(shot_b, mods, "carrier")
            assert not np.allclose(_mesh_points(body_b.data).mean(0), before[0].mean(0))
            assert not np.allclose(_carried_matrices(carrier_b, mods), before[1])
        assert _shown_debug(shot_a, mods, "baked:body") == body_a
        np.testing.assert_array_equal(_mesh_points(body_a.data), before[0])
        np.testing.assert_array_equal(_carried_matrices(carrier_a, mods), before[1])
    for coll in [c for c in bpy.data.collections if c.name.startswith(mods.nodes.DEBUG_COLLECTION)
                 and mods.owned.is_lixel_made(c)]:
        for ob in list(coll.objects):
            bpy.data.objects.remove(ob)
        bpy.data.collections.remove(coll)

def test_texel_grid_frustum_and_sync(scene, mods):
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    assert ground.modifiers[mods.nodes.TEXEL_MODIFIER].node_group.name == mods.nodes.TEXEL_GROUP
    assert bpy.ops.lixel.frustum_add() == {"FINISHED"}
    assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
    with pytest.raises(RuntimeError, match="map 7 does not exist"):
        bpy.ops.lixel.frustum_add(map_index=7)
    assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
    assert mods.nodes.TEXEL_MODIFIER not in ground.modifiers


def test_followers_of_a_map_the_setup_no_longer_has_are_named_when_the_matrices_are_written(scene, mods, capfd):
    """A frustum object of the cascade's map 3, then the method set to LiSPSM (one map) and Sync Light Matrices: the
    frustum's group read a zero matrix and showed a 2-unit cube at the origin, the texel grid of map 3 no texel's
    colour, and "1 matrices synced" said nothing of them. Each writing of the matrices names them; the frustum
    draws nothing."""
    ground = scene.objects["lixel_ops ground"]
    scene.lixel.method = "cascade"
    assert bpy.ops.lixel.frustum_add(map_index=3) == {"FINISHED"}
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add(map_index=2) == {"FINISHED"}
    assert "Warning" not in capfd.readouterr().out
    scene.lixel.method = "lispsm"
    assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
    assert ("Warning: Lixel: 'Lixel Frustum (map 3)' (map 3), 'lixel_ops ground' (map 2) follow a map the lispsm "
            "setup does not have (map 0 only): what they show belongs to no map; add them again for one of its maps, "
            "or delete them") in capfd.readouterr().out
    frustum = scene.objects["Lixel Frustum (map 3)"]
    corners = [tuple(v.co) for v in frustum.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices]
    assert corners == []        # no 2-unit cube at the origin, a box of no map (tests/blender/test_nodes.py)
    assert bpy.ops.lixel.texel_grid_add(map_index=0) == {"FINISHED"}       # the grid follows map 0 again
    assert "'lixel_ops ground'" not in capfd.readouterr().out


def test_many_followers_of_a_map_the_setup_no_longer_has_are_counted_past_five(scene, mods, capfd):
    """Texel grids of the cascade's map 2 on many objects, then one map: the warning named every object, and Blender
    cuts a report at about 1,000 characters, so with thousands of tiles it lost what to do. Five are named (in name
    order), the rest counted, and the remedy is said whole."""
    ground = scene.objects["lixel_ops ground"]
    tiles = [bpy.data.objects.new(f"lixel_ops tile {i}", ground.data) for i in range(7)]
    try:
        for ob in tiles:
            scene.collection.objects.link(ob)
        scene.lixel.method = "cascade"
        _select_only(scene, [ob.name for ob in tiles])
        assert bpy.ops.lixel.texel_grid_add(map_index=2) == {"FINISHED"}
        capfd.readouterr()
        scene.lixel.method = "lispsm"
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        named = ", ".join(f"'lixel_ops tile {i}' (map 2)" for i in range(5))
        assert (f"Warning: Lixel: {named} and 2 more follow a map the lispsm setup does not have (map 0 only): what "
                f"they show belongs to no map; add them again for one of its maps, or delete them") in \
            capfd.readouterr().out
    finally:
        for ob in tiles:
            bpy.data.objects.remove(ob)

def test_texel_grid_leaves_objects_linked_from_a_library_and_says_so(scene, tmp_path):
    """A modifier or material put on linked data is not saved with the file: the grid would vanish on reload."""
    me = bpy.data.meshes.new("library block")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    block = bpy.data.objects.new("library block", me)
    bpy.data.libraries.write(str(tmp_path / "library.blend"), {block})
    bpy.data.objects.remove(block)
    bpy.data.meshes.remove(me)
    with bpy.data.libraries.load(str(tmp_path / "library.blend"), link=True) as (_src, dst):
        dst.objects = ["library block"]
    linked = dst.objects[0]
    try:
        scene.collection.objects.link(linked)
        ground = scene.objects["lixel_ops ground"]
        _select_only(scene, [linked.name])
        with pytest.raises(RuntimeError, match="'library block' is linked from library.blend: make it local"):
            bpy.ops.lixel.texel_grid_add()
        _select_only(scene, [ground.name, linked.name])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert len(ground.modifiers) == 1 and len(linked.modifiers) == 0 and len(linked.data.materials) == 0
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
    finally:
        library = linked.library
        bpy.data.objects.remove(linked)
        bpy.data.libraries.remove(library)


def test_texel_grid_on_many_linked_objects_names_a_few_and_counts_the_rest(scene, tmp_path):
    """Selecting a linked set of tiles with a mesh of the file's own: the warning named every linked object, and
    Blender cuts a report at about 1,000 characters, so with 4,000 tiles the user read 1,000 characters of names,
    '... truncated', and neither why nor what to do. It names five (in name order) and counts the rest; the file's
    own mesh gets its grid."""
    me = bpy.data.meshes.new("library tile")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    tiles = [bpy.data.objects.new(f"library tile {i}", me) for i in range(8)]
    bpy.data.libraries.write(str(tmp_path / "tiles.blend"), set(tiles))
    for ob in tiles:
        bpy.data.objects.remove(ob)
    bpy.data.meshes.remove(me)
    with bpy.data.libraries.load(str(tmp_path / "tiles.blend"), link=True) as (_src, dst):
        dst.objects = [f"library tile {i}" for i in range(8)]
    linked = sorted(dst.objects, key=lambda ob: ob.name)
    try:
        for ob in linked:
            scene.collection.objects.link(ob)
        ground = scene.objects["lixel_ops ground"]
        _select_only(scene, [ground.name] + [ob.name for ob in linked])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert len(ground.modifiers) == 1 and not any(ob.modifiers for ob in linked)
        _select_only(scene, [ob.name for ob in linked])
        with pytest.raises(RuntimeError) as refused:
            bpy.ops.lixel.texel_grid_add()
        named = ", ".join(f"'library tile {i}'" for i in range(5))
        assert f"{named} and 3 more are linked from tiles.blend: make it local" in str(refused.value), refused.value
        assert "'library tile 5'" not in str(refused.value)
    finally:
        library = linked[0].library
        for ob in linked:
            bpy.data.objects.remove(ob)
        bpy.data.libraries.remove(library)

WRITES_SCENE = [("reset_settings", {}), ("bake_debug", {}), ("frustum_add", {}), ("sync_matrices", {}),
                ("texel_grid_add", {}), ("planes_from_selection", {}), ("plane_remove", {})]


def test_a_scene_linked_from_a_library_is_read_only_to_the_operators_that_change_it(lixel, tmp_path):
    """A linked scene cannot keep what an operator writes (and Blender refuses to link objects into it): the
    operators that change it say so by name, with the library, instead of reporting a bug or changing settings
    that would silently revert on reload; those that only read it still work."""
    with active_scene("lixel_library_scene") as sc:
        sc.lixel.method, sc.lixel.initialised = "uniform", True
        sc.lixel.planes.add().source = "kept"
        bpy.data.libraries.write(str(tmp_path / "scenes.blend"), {sc})
    with bpy.data.libraries.load(str(tmp_path / "scenes.blend"), link=True) as (_src, dst):
        dst.scenes = ["lixel_library_scene"]
    linked = dst.scenes[0]
    n_objects = len(bpy.data.objects)
    try:
        with bpy.context.temp_override(scene=linked, view_layer=linked.view_layers[0]):
            for op, kw in WRITES_SCENE:
                with pytest.raises(RuntimeError, match="Scene 'lixel_library_scene' is linked from scenes.blend and "
                                                       "cannot be changed here: make it local") as err:
                    getattr(bpy.ops.lixel, op)(**kw)
                assert "a bug in Lixel" not in str(err.value)
            assert bpy.ops.lixel.refresh() == {"FINISHED"}
            assert bpy.ops.lixel.export_json(filepath=str(tmp_path / "linked.json")) == {"FINISHED"}
        assert linked.lixel.method == "uniform" and [p.source for p in linked.lixel.planes] == ["kept"]
        assert len(bpy.data.objects) == n_objects and "Lixel Debug" not in bpy.data.collections
    finally:
        library = linked.library
        bpy.data.scenes.remove(linked)
        bpy.data.libraries.remove(library)

OVERRIDE_RELOADED = """
import json, sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1], load_ui=False)
ob = next(ob for ob in bpy.data.objects if ob.library is None and ob.name == sys.argv[2])
me = ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
print("RELOADED", json.dumps({"modifiers": [m.name for m in ob.modifiers],
                              "material": [m.name for m in me.materials if m is not None],
                              "attributes": sorted(a.name for a in me.attributes if a.name.startswith("lixel_")),
                              "color_names": [ob.data.attributes.active_color_name,
                                              ob.data.attributes.default_color_name]}))
"""


def _overridden_from_library(scene, coll, path):
    """``coll`` written to the library file ``path`` and removed here with its objects and their meshes, then linked
    back and overridden (Object > Library Override > Make): (the library, the override's collection)."""
    bpy.data.libraries.write(str(path), {coll})
    name, meshes = coll.name, [ob.data for ob in coll.objects]
    for ob in list(coll.objects):
        bpy.data.objects.remove(ob)
    for me in meshes:
        bpy.data.meshes.remove(me)
    bpy.data.collections.remove(coll)
    with bpy.data.libraries.load(str(path), link=True) as (_src, dst):
        dst.collections = [name]
    return dst.collections[0].library, dst.collections[0].override_hierarchy_create(scene, bpy.context.view_layer)


@pytest.mark.parametrize("mesh_too", [False, True, None], ids=["linked mesh", "overridden mesh",
                                                               "a local object's linked mesh"])
def test_texel_grid_on_a_library_override_is_saved_and_leaves_its_mesh_as_it_is(scene, mods, tmp_path, capfd,
                                                                                  mesh_too):
    """Object > Library Override > Make overrides the objects and keeps their meshes linked; Add Texel Grid refused
    them ("make the mesh local") although the grid needs no material slot any more, only a modifier, which an
    override keeps. The grid goes on, is there after saving and reloading, and the mesh is left as it is: its
    colour attribute names on a linked mesh would not be saved, and on an overridden one come back empty. The user
    is told that Workbench's Attribute colour (which reads those names) does not show it, and what to do."""
    import subprocess
    import sys
    me = bpy.data.meshes.new("override block")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    coll = bpy.data.collections.new("override coll")
    coll.objects.link(bpy.data.objects.new("override block", me))
    library, override = _overridden_from_library(scene, coll, tmp_path / "library.blend")
    ob = override.objects[0]
    if mesh_too:
        ob.data = ob.data.override_create(remap_local_usages=True)
    elif mesh_too is None:  # Make Local > Selected Objects: the object the file's own, its mesh still linked
        ob = ob.make_local(clear_liboverride=True)
    mesh = ob.data
    try:
        assert (ob.override_library is not None) == (mesh_too is not None) and ob.library is None
        assert (mesh.override_library is not None) == bool(mesh_too) and (mesh.library is None) == bool(mesh_too)
        _select_only(scene, [ob.name])
        capfd.readouterr()
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert [m.name for m in ob.modifiers] == [mods.nodes.TEXEL_MODIFIER]
        assert (mesh.attributes.active_color_name, mesh.attributes.default_color_name, len(mesh.materials)) == \
            ("", "", 0)
        assert (f"Warning: Lixel: the mesh of '{ob.name}' is library.blend's: the grid shows in Material Preview and "
                f"Rendered shading, not in Workbench's Attribute colour; for that, make the mesh local (Object > "
                f"Relations > Make Local > Selected Objects and Data)") in capfd.readouterr().out
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"), copy=True)
        proc = subprocess.run([sys.executable, "-c", OVERRIDE_RELOADED, str(tmp_path / "shot.blend"), ob.name],
                              capture_output=True, text=True, timeout=300)
        reloaded = [line.split(" ", 1)[1] for line in proc.stdout.splitlines() if line.startswith("RELOADED ")]
        assert reloaded, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert json.loads(reloaded[0]) == {
            "modifiers": [mods.nodes.TEXEL_MODIFIER], "material": [mods.nodes.TEXEL_MATERIAL], "color_names": ["", ""],
            "attributes": sorted([mods.nodes.XYW_ATTRIBUTE, mods.nodes.TEXEL_ATTRIBUTE, mods.nodes.SIZE_ATTRIBUTE,
                                  mods.nodes.PARITY_COLOR_ATTRIBUTE])}
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert len(ob.modifiers) == 0 and (mesh.attributes.active_color_name, len(mesh.materials)) == ("", 0)
    finally:
        bpy.data.objects.remove(ob)
        if mesh_too:
            bpy.data.meshes.remove(mesh)
        bpy.data.collections.remove(override)
        bpy.data.libraries.remove(library)


def test_remove_texel_grid_says_an_override_cannot_remove_the_grid_its_library_gave_it(scene, mods, tmp_path,
                                                                                       capfd):
    """An asset whose library file has the texel grid, overridden here: Remove Texel Grid said it removed the grid,
    and it came back when the file was opened (an override cannot remove its reference's modifier). The override
    is left with its grid and named with what to do; a grid of the file's own is removed beside it."""
    ground = scene.objects["lixel_ops ground"]
    me = bpy.data.meshes.new("gridded block")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    coll = bpy.data.collections.new("gridded coll")
    coll.objects.link(bpy.data.objects.new("gridded block", me))
    scene.collection.children.link(coll)
    _select_only(scene, [coll.objects[0].name, ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    library, override = _overridden_from_library(scene, coll, tmp_path / "assets.blend")
    ob = override.objects[0]
    try:
        said = (r"'gridded block' has its texel grid from assets.blend, which a library override cannot remove \(it "
                r"comes back when the file is opened\): switch the 'Lixel Texel Grid' modifier off")
        _select_only(scene, [ob.name])
        with pytest.raises(RuntimeError, match=said):
            bpy.ops.lixel.texel_grid_add(remove=True)
        _select_only(scene, [ob.name, ground.name])
        capfd.readouterr()
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        assert [m.name for m in ob.modifiers] == [mods.nodes.TEXEL_MODIFIER] and len(ground.modifiers) == 0
        out = capfd.readouterr().out
        assert "Warning: Lixel: 'gridded block' has its texel grid from assets.blend" in out, out
        assert "Info: Lixel: removed the texel grid from 1 object(s)" in out, out
    finally:
        bpy.data.objects.remove(ob)
        bpy.data.collections.remove(override)
        bpy.data.libraries.remove(library)


def _evaluated_texels(ob, nodes):
    dg = bpy.context.evaluated_depsgraph_get()
    dg.update()
    me = ob.evaluated_get(dg).data
    texels = np.zeros(len(me.vertices) * 3, dtype=np.float32)
    me.attributes[nodes.TEXEL_ATTRIBUTE].data.foreach_get("vector", texels)
    return texels


def test_a_full_copy_of_the_scene_keeps_its_texel_grid_following_sync_and_bake_replacing(scene, mods):
    """Scene > New > Full Copy copies the "Lixel Debug" collection and its objects under copies' names, and the
    copied texel grid follows the copied carrier. Lixel took those copies for the user's: Sync in the new scene wrote
    a second carrier the grid did not follow (it kept the matrices of the copy, without a word), and Bake a second
    set of objects beside the stale copies. The copy is the new scene's now: Sync moves its grid, Bake replaces its
    objects, the first scene's are left as they were, and an object the user kept with Shift+D is kept in both."""
    nodes = mods.nodes
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"} and bpy.ops.lixel.bake_debug() == {"FINISHED"}
    coll = bpy.data.collections["Lixel Debug"]
    kept = coll.objects["Lixel B"].copy()    # the user's Shift+D copy of the baked B, kept
    kept.data = kept.data.copy()
    coll.objects.link(kept)
    texels = _evaluated_texels(ground, nodes)
    window = bpy.context.window
    assert bpy.ops.scene.new(type="FULL_COPY") == {"FINISHED"}
    copy = window.scene
    try:
        copied = {ob.name for ob in copy.objects}
        counts = len(bpy.data.objects), len(bpy.data.collections)
        ground_copy = next(ob for ob in copy.objects if ob.data.name.startswith(ground.data.name))
        light = next(ob for ob in copy.objects if ob.type == "LIGHT")
        light.rotation_euler.x += 0.3
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        assert np.abs(_evaluated_texels(ground_copy, nodes) - texels).max() > 1.0
        assert bpy.ops.lixel.bake_debug() == {"FINISHED"}
        new = {ob.name for ob in copy.objects} - copied
        assert len(new) == 1 and next(iter(new)).startswith("Lixel B"), new   # B: the two copies of it are kept
        assert (len(bpy.data.objects), len(bpy.data.collections)) == (counts[0] + 1, counts[1])
        window.scene = scene
        np.testing.assert_array_equal(_evaluated_texels(ground, nodes), texels)
        assert bpy.ops.lixel.bake_debug() == {"FINISHED"} and kept.name in coll.objects
    finally:
        window.scene = scene
        children = list(copy.collection.children)
        remove_scene(copy)  # its objects and the data only they used (Lixel's marked meshes must not outlive it)
        for c in children:
            bpy.data.collections.remove(c)


def _mesh_co(mesh):
    co = np.zeros(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    return co


def test_a_linked_copy_of_the_scene_leaves_the_first_scenes_grid_and_baked_objects_alone(scene, mods, capfd):
    """Scene > New > Linked Copy links the same "Lixel Debug" collection (and the same objects) into the new scene.
    Sync and Bake in the copy, set to another method, rewrote the first scene's carrier and baked B: its texel grid
    and B showed the copy's setup without a word. The copy takes its own collection now; the ground both scenes
    hold follows one scene's matrices, and Sync in the other says so, naming it and what to do."""
    nodes = mods.nodes
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"} and bpy.ops.lixel.bake_debug() == {"FINISHED"}
    coll = bpy.data.collections["Lixel Debug"]
    first = {ob.name: _mesh_co(ob.data) for ob in coll.objects}
    texels = _evaluated_texels(ground, nodes)
    window = bpy.context.window
    assert bpy.ops.scene.new(type="LINK_COPY") == {"FINISHED"}
    copy = window.scene
    try:
        copy.lixel.method = "uniform" if scene.lixel.method != "uniform" else "psm"
        capfd.readouterr()
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"} and bpy.ops.lixel.bake_debug() == {"FINISHED"}
        out = capfd.readouterr().out
        np.testing.assert_array_equal(_evaluated_texels(ground, nodes), texels)
        assert {ob.name: _mesh_co(ob.data) for ob in coll.objects}.keys() == first.keys()
        for name, co in first.items():
            np.testing.assert_array_equal(_mesh_co(coll.objects[name].data), co)
        own = copy.lixel.debug_collection
        assert own != coll and own.name in copy.collection.children and coll.name not in copy.collection.children
        assert ("'lixel_ops ground' (follows 'Lixel Light Matrices' of scene 'lixel_ops') shows light matrices that "
                f"are not this scene's '{own.objects[0].name}', so it does not follow the setup: select it and Add "
                "Texel Grid") in out, out
        window.scene = scene
        capfd.readouterr()
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"} and bpy.ops.lixel.bake_debug() == {"FINISHED"}
        assert "Warning" not in capfd.readouterr().out
        assert scene.lixel.debug_collection == coll and coll.name in scene.collection.children
    finally:
        window.scene = scene
        own = copy.lixel.debug_collection
        bpy.data.scenes.remove(copy)
        if own is not None and own != coll:
            for ob in list(own.objects):
                mesh = ob.data
                bpy.data.objects.remove(ob)
                if mesh is not None and mesh.users == 0:
                    bpy.data.meshes.remove(mesh)
            bpy.data.collections.remove(own)


def test_sync_names_a_texel_grid_that_follows_a_carrier_the_user_renamed(scene, mods, capfd):
    """The user renamed Lixel's "Lixel Light Matrices" (it is theirs from then on: Lixel never rewrites it). Sync
    wrote a new carrier and said "1 matrices synced", while the texel grid kept following the renamed one and showed
    the old matrices without a word. Sync names it and what to do; Add Texel Grid makes it follow again."""
    nodes = mods.nodes
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    texels = _evaluated_texels(ground, nodes)
    bpy.data.objects["Lixel Light Matrices"].name = "my matrices"
    scene.objects["lixel_ops light"].rotation_euler.x += 0.3
    capfd.readouterr()
    assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
    assert ("Warning: Lixel: 'lixel_ops ground' (follows 'my matrices') shows light matrices that are not this "
            "scene's 'Lixel Light Matrices', so it does not follow the setup: select it and Add Texel Grid (a "
            "frustum: Add Frustum From Matrix) to follow it") in capfd.readouterr().out
    np.testing.assert_array_equal(_evaluated_texels(ground, nodes), texels)
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"} and bpy.ops.lixel.sync_matrices() == {"FINISHED"}
    assert "Warning" not in capfd.readouterr().out
    assert np.abs(_evaluated_texels(ground, nodes) - texels).max() > 1.0


@pytest.mark.parametrize("has_group", [True, False])
def test_an_object_appended_with_its_texel_grid_has_it_removed_and_replaced(scene, mods, capfd, tmp_path, has_group):
    """File > Append of an object with Lixel's texel grid from another .blend. Where this file has Lixel's group
    already, Blender names the appended one "Lixel Texel Grid.001", and Lixel took its modifier for a user's: Remove
    Texel Grid said "removed the texel grid from 0 object(s)" and left it, Add Texel Grid stacked a second grid on it.
    Where it has none, Remove Texel Grid stopped in "unexpected error ... this is a bug in Lixel": an appended
    object's modifiers say ``is_override_data`` as an override's do. A copy of the group the user edited is theirs."""
    nodes = mods.nodes
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    library = str(tmp_path / "library.blend")
    bpy.data.libraries.write(library, {ground})
    if not has_group:
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        bpy.data.node_groups.remove(bpy.data.node_groups[nodes.TEXEL_GROUP])
    with bpy.data.libraries.load(library, link=False) as (_src, dst):
        dst.objects = [ground.name]
    (appended,) = dst.objects
    scene.collection.objects.link(appended)
    try:
        assert appended.modifiers[0].node_group.name == nodes.TEXEL_GROUP + (".001" if has_group else "")
        _select_only(scene, [appended.name])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert [m.node_group.name for m in appended.modifiers] == [nodes.TEXEL_GROUP]     # the same one, updated
        capfd.readouterr()
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"} and len(appended.modifiers) == 0
        assert "Info: Lixel: removed the texel grid from 1 object(s)" in capfd.readouterr().out
        copy = nodes.ensure_texel_grid_group().copy()      # the user's copy, edited
        next(n for n in copy.nodes if n.bl_idname not in ("NodeGroupInput", "NodeGroupOutput")).mute = True
        appended.modifiers.new(nodes.TEXEL_MODIFIER, "NODES").node_group = copy
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"} and len(appended.modifiers) == 1
    finally:
        bpy.data.objects.remove(appended)


def test_reset_settings_keeps_light_and_planes(scene):
    props = scene.lixel
    props.pcf_kernel = 5
    props.planes.add().normal = (0, 1, 0)
    assert bpy.ops.lixel.reset_settings() == {"FINISHED"}
    assert props.pcf_kernel == props.bl_rna.properties["pcf_kernel"].default != 5
    assert len(props.planes) == 1


@pytest.mark.parametrize("size", [(0, 0), (-5, -5), (8, 2048), (65536, 65536), (2048, 16385)])
def test_map_size_outside_the_limits_is_refused_not_clamped(scene, mods, size):
    scene.lixel.initialised = True
    scene.lixel.shadow_map_size = size
    assert tuple(scene.lixel.shadow_map_size) == size  # kept as typed, so it can be named
    w, h = size
    with pytest.raises(RuntimeError, match=rf"Scene 'lixel_ops' has a shadow map size of {w}x{h}, out of range: "
                                           rf"use 16\.\.16384"):
        bpy.ops.lixel.refresh()
    assert not mods.live.state(scene).ok


NEEDS_SETUP = [
    ("refresh", {}),
    ("bake_debug", {}),
    ("export_json", {"filepath": "/nonexistent/never_written.json"}),
    ("compare", {}),
    ("sync_matrices", {}),
    ("frustum_add", {}),
]


@pytest.mark.parametrize("missing,pattern", [
    ("camera", "no camera"),
    ("light", "no light"),
    ("mesh", "no visible faces"),
])
@pytest.mark.parametrize("op,kw", NEEDS_SETUP)
def test_missing_input_is_reported_clearly(lixel, missing, pattern, op, kw):
    with active_scene(f"lixel_missing_{missing}", camera=missing != "camera", light=None if missing == "light" else "SUN",
                      mesh=missing != "mesh") as sc:
        n_objects = len(bpy.data.objects)
        with pytest.raises(RuntimeError, match=pattern):
            getattr(bpy.ops.lixel, op)(**kw)
        assert len(bpy.data.objects) == n_objects
        assert "Lixel Debug" not in bpy.data.collections
        assert sc.lixel.planes is not None


def test_a_camera_that_sees_nothing_to_shadow_is_named_with_what_to_do(scene):
    """A camera turned to the sky: the report names the camera and the light and says what to change, instead of
    the core's bare "the camera sees no shadow receiver (scene boxes)"."""
    scene.objects["lixel_ops camera"].rotation_euler = (3.14159, 0.0, 0.0)    # looking straight up
    with pytest.raises(RuntimeError, match=r"Camera 'lixel_ops camera' and light 'lixel_ops light' leave Lixel "
                                           r"nothing to shadow: the camera sees no shadow receiver .*; aim the camera"):
        bpy.ops.lixel.refresh()

def test_texel_grid_without_mesh_or_camera(lixel):
    with active_scene("lixel_missing_grid", camera=False) as sc:
        _select_only(sc, [])
        with pytest.raises(RuntimeError, match="no mesh selected"):
            bpy.ops.lixel.texel_grid_add()
        _select_only(sc, [sc.objects["lixel_missing_grid ground"].name])
        with pytest.raises(RuntimeError, match="no camera"):
            bpy.ops.lixel.texel_grid_add()
        assert len(sc.objects["lixel_missing_grid ground"].modifiers) == 0


def test_overlay_on_in_a_scene_without_camera_says_why(lixel, mods):
    with active_scene("lixel_missing_overlay", camera=False) as sc:
        with pytest.raises(RuntimeError, match="no camera"):
            bpy.ops.lixel.toggle_overlay(overlay="show_body")
        assert sc.lixel.show_body  # the overlay is on and will draw once there is a camera
        sc.lixel.show_body = False
        mods.overlays.sync_handlers()
        assert mods.overlays.draw_handlers_active() == ()


CHANGES_DATA = ("refresh", "toggle_overlay", "export_json", "reset_settings", "bake_debug", "texel_grid_add",
                "frustum_add", "sync_matrices", "compare", "planes_from_selection", "plane_remove", "overlay_snapshot")


def test_every_operator_that_changes_data_can_be_undone(lixel):
    """Each of these writes scene data (a first refresh or export sets the scene
    up, toggling an overlay writes its switch): each gets an undo step."""
    ops = importlib.import_module(f"{lixel.__name__}.addon.ui.operators")
    options = {c.bl_idname: c.bl_options for c in ops.classes}
    assert [n for n in CHANGES_DATA if "UNDO" not in options[f"lixel.{n}"]] == []


@pytest.fixture
def file_size_limit():
    """A write failing part-way, as on a full disk: files may not grow past ``limit`` bytes (RLIMIT_FSIZE; the
    signal it sends is ignored so the write fails with EFBIG instead)."""
    import resource
    import signal
    old_limit, old_handler = resource.getrlimit(resource.RLIMIT_FSIZE), signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    def limit(n):
        resource.setrlimit(resource.RLIMIT_FSIZE, (n, old_limit[1]))
    yield limit
    resource.setrlimit(resource.RLIMIT_FSIZE, old_limit)
    signal.signal(signal.SIGXFSZ, old_handler)


def test_an_export_that_fails_part_way_leaves_the_file_that_was_there(scene, tmp_path, file_size_limit):
    """Exporting over an existing file opened it for writing, which emptied it, then wrote: a write that failed
    part-way (a full disk) left the user's file gone and 256 bytes of half a JSON document in its place. The
    export is written beside it and renamed over it only when whole; a failed one is said and leaves no file."""
    path = tmp_path / "setup.json"
    path.write_text('{"the user\'s": "earlier export"}\n')
    path.chmod(0o640)
    file_size_limit(256)
    with pytest.raises(RuntimeError, match=r"cannot write '.*setup\.json': File too large"):
        bpy.ops.lixel.export_json(filepath=str(path), all_methods=True)
    file_size_limit(-1)
    assert path.read_text() == '{"the user\'s": "earlier export"}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["setup.json"]
    assert bpy.ops.lixel.export_json(filepath=str(path)) == {"FINISHED"}
    assert set(json.loads(path.read_text())) == {"maps", "diagnostics"} and (path.stat().st_mode & 0o777) == 0o640


def test_a_lixel_group_whose_inputs_the_user_took_out_is_named_not_a_bug(scene, mods, capfd):
    """The user edits Lixel's Texel Grid group without renaming it and takes out its Map Index input. Sync and Add
    Texel Grid said "unexpected error ... this is a bug in Lixel" (a KeyError reading the modifier's inputs). Now
    Sync passes the group by, and Add names the group, the input and what to do."""
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    group = ground.modifiers[mods.nodes.TEXEL_MODIFIER].node_group
    item = next(i for i in group.interface.items_tree if getattr(i, "in_out", "") == "INPUT" and i.name == "Map Index")
    group.interface.remove(item)
    try:
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        cube = scene.objects["lixel_ops cube"]
        _select_only(scene, [ground.name, cube.name])
        with pytest.raises(RuntimeError) as refused:
            bpy.ops.lixel.texel_grid_add()
        assert "bug" not in str(refused.value) and len(cube.modifiers) == 0        # refused before any change
        assert (f"node group '{group.name}' has no input 'Map Index' (was it edited?): rename it to keep it as yours, "
                f"and Lixel builds its own again") in str(refused.value), str(refused.value)
        group.name = "my grid"
        _select_only(scene, [ground.name])
        assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
        assert mods.nodes.lixel_modifier(ground, mods.nodes.TEXEL_MODIFIER).node_group not in (group, None)
    finally:
        for mod in [m for m in ground.modifiers if m.type == "NODES"]:
            ground.modifiers.remove(mod)
        bpy.data.node_groups.remove(group)


def test_frusta_and_texel_grids_of_a_deleted_carrier_follow_the_new_one(scene, mods, capfd):
    """The user deletes the "Lixel Light Matrices" object: Blender clears the Light Matrices of every frustum and
    texel grid following it, and Sync made a new carrier, said "1 matrices synced", and left them showing nothing
    (no volume, no texels) with no word. Now each writing of the matrices points the scene's orphaned Lixel
    modifiers at the new carrier and names their objects."""
    ground = scene.objects["lixel_ops ground"]
    _select_only(scene, [ground.name])
    assert bpy.ops.lixel.frustum_add() == {"FINISHED"}
    assert bpy.ops.lixel.texel_grid_add() == {"FINISHED"}
    frustum = scene.objects["Lixel Frustum (map 0)"]
    deleted = scene.objects[mods.nodes.CARRIER_NAME]
    orphan = deleted.data               # (Blender keeps the mesh until the file is saved; the test takes it away)
    bpy.data.objects.remove(deleted)
    capfd.readouterr()
    try:
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        carrier = mods.nodes.scene_debug_object(scene, mods.nodes.CARRIER_NAME)
        assert (f"Info: Lixel: 'lixel_ops ground', 'Lixel Frustum (map 0)' followed no light matrices (the "
                f"'{mods.nodes.CARRIER_NAME}' object they followed was deleted): they follow '{carrier.name}' "
                f"again") in capfd.readouterr().out
        dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        assert len(frustum.evaluated_get(dg).data.vertices) == 8
        assert mods.nodes.TEXEL_ATTRIBUTE in ground.evaluated_get(dg).data.attributes
        assert bpy.ops.lixel.sync_matrices() == {"FINISHED"}
        assert "followed no light matrices" not in capfd.readouterr().out
    finally:
        assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
        bpy.data.meshes.remove(orphan)
