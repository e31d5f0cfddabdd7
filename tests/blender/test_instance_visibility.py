"""Which objects the camera sees and which cast, as Cycles decides it (addon/scene/instances.py, ``_seen``): an
instancer's Ray Visibility is inherited by its instances, and a collection rendered Indirect Only is hidden from the
camera alone. Measured with Cycles in 4.2.23 and 5.0.1 (a 0.9 cube before the box on a sun-lit ground). Before,
Lixel read each instanced object's own flags only (an empty instancing a collection with Shadow off still cast its
instances' shadows) and drew Indirect Only objects as any other."""
import bpy
import numpy as np
import pytest

from test_render_engine import (_add_hold, _instanced_pixels, _instancer, _remove_instancer, _render, build,  # noqa: F401
                                cube_mesh, scene)


def _cycles(scene, tmp_path, load_pixels) -> np.ndarray:
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 16, False, "CPU"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    try:
        assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    finally:
        scene.render.engine = "LIXEL"
    return load_pixels(scene.render.filepath)


@pytest.mark.parametrize("flag", ["visible_shadow", "visible_camera"])
@pytest.mark.parametrize("kind", ["collection", "nodes"])
def test_an_instancers_ray_visibility_is_inherited_by_its_instances(engine, scene, kind, flag, tmp_path,
                                                                    load_pixels):
    """Shadow (or Camera) off on the instancer renders, in Cycles and in Lixel, as it off on the instanced cube;
    Lixel's render differs from the plain one (the flag does something) and equals the other bit for bit."""
    build(scene)
    instanced = bpy.data.objects.new("Hold", cube_mesh("Hold", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    try:
        plain = _render(engine, scene, read={"world_position"})["result"]
        got, cycles = {}, {}
        for who in (host, instanced):
            setattr(who, flag, False)
            got[who.name] = _render(engine, scene)["result"]
            cycles[who.name] = _cycles(scene, tmp_path, load_pixels)
            setattr(who, flag, True)
    finally:
        _remove_instancer(host, instanced)
    assert _instanced_pixels(plain.world_position).sum() > 100
    np.testing.assert_allclose(cycles[host.name], cycles["Hold"], atol=1e-3)
    assert np.abs(got["Hold"].combined - plain.combined).max() > 0.1
    np.testing.assert_array_equal(got[host.name].combined, got["Hold"].combined)
    np.testing.assert_array_equal(got[host.name].shadow_mask, got["Hold"].shadow_mask)


def _indirect_only(scene, *objects):
    """A collection of ``objects`` (moved out of the scene's own), rendered Indirect Only in the view layer."""
    coll = bpy.data.collections.new("lixel_test indirect")
    scene.collection.children.link(coll)
    for ob in objects:
        scene.collection.objects.unlink(ob)
        coll.objects.link(ob)
    scene.view_layers[0].update()
    scene.view_layers[0].layer_collection.children[coll.name].indirect_only = True
    return coll


def _dissolve(scene, coll) -> None:
    for ob in list(coll.objects):                     # back in the scene, which the fixture clears
        coll.objects.unlink(ob)
        scene.collection.objects.link(ob)
    bpy.data.collections.remove(coll)


def test_an_indirect_only_collection_is_hidden_from_the_camera_alone(engine, scene, tmp_path, load_pixels):
    """The cube before the box in an Indirect Only collection renders as with its Ray Visibility > Camera off, in
    Cycles (to its noise) and in Lixel (bit for bit): the box and ground seen through it, its shadow kept."""
    build(scene)
    hold = _add_hold(scene)
    plain = _render(engine, scene)["result"]
    hold.visible_camera = False
    unseen, cycles_unseen = _render(engine, scene)["result"], _cycles(scene, tmp_path, load_pixels)
    hold.visible_camera = True
    coll = _indirect_only(scene, hold)
    try:
        got, cycles = _render(engine, scene)["result"], _cycles(scene, tmp_path, load_pixels)
    finally:
        _dissolve(scene, coll)
    assert np.abs(cycles - cycles_unseen).mean() < 0.01
    assert np.abs(unseen.combined - plain.combined).max() > 0.1
    np.testing.assert_array_equal(got.combined, unseen.combined)
    np.testing.assert_array_equal(got.shadow_mask, unseen.shadow_mask)


@pytest.mark.parametrize("kind", ["collection", "nodes"])
def test_an_indirect_only_instancers_instances_are_hidden_from_the_camera(engine, scene, kind):
    """The instancer in an Indirect Only collection: its instances render as with the instanced cube's Camera off."""
    build(scene)
    instanced = bpy.data.objects.new("Hold", cube_mesh("Hold", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    try:
        plain = _render(engine, scene)["result"]
        instanced.visible_camera = False
        unseen = _render(engine, scene)["result"]
        instanced.visible_camera = True
        coll = _indirect_only(scene, host)
        try:
            got = _render(engine, scene)["result"]
        finally:
            _dissolve(scene, coll)
    finally:
        _remove_instancer(host, instanced)
    assert np.abs(unseen.combined - plain.combined).max() > 0.1
    np.testing.assert_array_equal(got.combined, unseen.combined)
