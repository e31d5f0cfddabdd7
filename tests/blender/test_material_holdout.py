"""A material's Holdout shader holds the surface out as Cycles does (addon/scene/materials.py; measured in 4.2.23 and
5.0.1: the surface a transparent hole, everything else as with Object > Visibility > Holdout, its shadow kept).
Before, Lixel drew such a surface as any other, lit grey (0.50 where Cycles' hole read alpha 0.03)."""
import bpy
import numpy as np
import pytest

from test_render_engine import (_add_hold, _inside, _instanced_pixels, _instancer, _remove_instancer, _render,  # noqa: F401
                                build, cube_mesh, scene)


def _holdout_material(name="lixel_test holdout"):
    material = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    tree.links.new(tree.nodes.new("ShaderNodeHoldout").outputs[0],
                   tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return material


@pytest.fixture
def holdout():
    material = _holdout_material()
    yield material
    bpy.data.materials.remove(material)


def _cycles_alpha(scene, tmp_path, load_pixels) -> np.ndarray:
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 16, False, "CPU"
    scene.render.image_settings.file_format, scene.render.image_settings.color_mode = "OPEN_EXR", "RGBA"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    try:
        assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    finally:
        scene.render.engine = "LIXEL"
    return load_pixels(scene.render.filepath)[..., 3]


def test_a_holdout_material_renders_as_the_objects_holdout(engine, scene, holdout, tmp_path, load_pixels):
    """The cube before the box with a Holdout material: Cycles leaves a hole (alpha under 0.1 over it); Lixel's
    render equals that with the object's Holdout on, bit for bit, no warning."""
    build(scene)
    hold = _add_hold(scene)
    plain = _render(engine, scene, read={"world_position"})
    hole = _inside(plain["result"].world_position, hold)
    assert hole.sum() > 100
    hold.is_holdout = True
    by_object = _render(engine, scene)
    hold.is_holdout = False
    hold.data.materials.append(holdout)
    by_material = _render(engine, scene)
    assert _cycles_alpha(scene, tmp_path, load_pixels)[hole].mean() < 0.1
    np.testing.assert_array_equal(by_material["result"].combined[hole], 0.0)
    np.testing.assert_array_equal(by_material["result"].combined, by_object["result"].combined)
    np.testing.assert_array_equal(by_material["result"].shadow_mask, by_object["result"].shadow_mask)
    assert not [w for w in by_material["warnings"] if "old" in w.lower()]


@pytest.mark.parametrize("kind", ["collection", "nodes"])
def test_an_instance_with_a_holdout_material_is_held_out(engine, scene, holdout, kind):
    """The material goes with the geometry: an instanced cube whose mesh has the Holdout is held out wherever it is
    instanced, by a collection instance (the walk) or by geometry nodes (4.3+: the array reader)."""
    build(scene)
    instanced = bpy.data.objects.new("Hold", cube_mesh("Hold", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    try:
        plain = _render(engine, scene, read={"world_position"})
        instanced.data.materials.append(holdout)
        cut = _render(engine, scene)
    finally:
        _remove_instancer(host, instanced)
    hole = _instanced_pixels(plain["result"].world_position)
    assert hole.sum() > 100
    np.testing.assert_array_equal(cut["result"].combined[hole], 0.0)
    np.testing.assert_array_equal(cut["result"].combined[~hole], plain["result"].combined[~hole])


def test_a_surface_held_out_in_part_is_named(engine, scene, holdout):
    """Half the cube's faces with the Holdout, half with another material (Cycles: a hole over those faces alone,
    mean alpha 0.48 over the cube): Lixel does not model it, renders the cube whole and names it and the material."""
    build(scene)
    hold = _add_hold(scene)
    plain = _render(engine, scene)
    other = bpy.data.materials.new("lixel_test other")
    hold.data.materials.append(holdout)
    hold.data.materials.append(other)
    for i, face in enumerate(hold.data.polygons):
        face.material_index = i % 2
    try:
        got = _render(engine, scene)
    finally:
        bpy.data.materials.remove(other)
    np.testing.assert_array_equal(got["result"].combined, plain["result"].combined)
    assert (f"Lixel: object 'Hold' holds out only part of its surface (material '{holdout.name}' has a Holdout "
            f"shader, its other materials or shaders do not): Lixel renders its whole surface as not held out; give "
            f"all its material slots the Holdout, or use Object properties > Visibility > Holdout") in got["warnings"]
