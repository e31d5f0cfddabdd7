"""Lixel lights a scene with the world Cycles renders (addon/scene/world.py): a world's node tree where it has one
(every new world in 5.0), ``world.color`` only where it has none (4.2). Before, Lixel read ``world.color`` always:
a new 5.0 world coloured (0.2, 0.3, 0.4) lit Lixel's picture with it while Cycles rendered its Background's 0.05."""
import importlib

import bpy
import numpy as np
import pytest

from worlds import background, sky_world

ALBEDO = 0.8            # Lixel's surface grey (addon.gpu.pipeline.DEFAULT_ALBEDO), given to Cycles' plane
SIZE = 32
PLANE = np.s_[10:22, 10:22]    # inside the plane, which fills the middle half of the frame
SKY = np.s_[0:4, 0:4]          # outside it: the world background


@pytest.fixture(scope="module")
def world_light(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.scene.world").world_light


@pytest.fixture
def scene(fresh_scene):
    """A grey diffuse plane seen from above by an orthographic camera, no light: the world lights it alone."""
    bpy.ops.mesh.primitive_plane_add(size=2)
    plane = bpy.context.object
    if plane.name not in fresh_scene.objects:
        fresh_scene.collection.objects.link(plane)
    material = bpy.data.materials.new("lixel_test grey")
    if bpy.app.version < (5, 0, 0):
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1.0)
    tree.links.new(diffuse.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    plane.data.materials.append(material)
    cam_data = bpy.data.cameras.new("lixel_test cam")
    cam_data.type, cam_data.ortho_scale = "ORTHO", 4.0
    cam = bpy.data.objects.new("lixel_test cam", cam_data)
    cam.location = (0.0, 0.0, 5.0)
    fresh_scene.collection.objects.link(cam)
    fresh_scene.camera = cam
    r = fresh_scene.render
    r.resolution_x = r.resolution_y = SIZE
    r.resolution_percentage = 100
    fresh_scene.view_settings.view_transform = "Standard"
    yield fresh_scene
    world = fresh_scene.world
    fresh_scene.world = None
    if world is not None:
        bpy.data.worlds.remove(world)
    bpy.data.materials.remove(material)


def _cycles(scene, tmp_path, load_pixels) -> np.ndarray:
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 16, False, "CPU"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    return load_pixels(scene.render.filepath)


def _lixel(engine, scene) -> dict:
    scene.render.engine = "LIXEL"
    with engine.watch_renders(read={"combined", "covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    assert got[-1]["result"].covered[PLANE].all() and not got[-1]["result"].covered[SKY].any()
    return got[-1]


def _new_world(scene):
    scene.world = bpy.data.worlds.new("lixel_test world")
    return scene.world


def _output(world):
    return next(n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD")


def a_new_worlds_colour(scene):
    """``world.color`` set on a new world: Cycles renders it in 4.2 (no nodes), the Background's 0.05 in 5.0."""
    _new_world(scene).color = (0.2, 0.3, 0.4)


def a_background_at_strength_2(scene):
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)


def a_background_fed_by_rgb_and_value_nodes(scene):
    world = _new_world(scene)
    node, tree = background(world), world.node_tree
    rgb, value = tree.nodes.new("ShaderNodeRGB"), tree.nodes.new("ShaderNodeValue")
    rgb.outputs[0].default_value, value.outputs[0].default_value = (0.5, 0.25, 0.1, 1.0), 1.5
    tree.links.new(rgb.outputs[0], node.inputs["Color"])
    tree.links.new(value.outputs[0], node.inputs["Strength"])


def an_emission_into_the_output(scene):
    world = _new_world(scene)
    background(world)
    emission = world.node_tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value, emission.inputs["Strength"].default_value = (0.2, 0.3, 0.4, 1.0), 2.0
    world.node_tree.links.new(emission.outputs[0], _output(world).inputs["Surface"])


def a_mix_of_two_backgrounds(scene):
    world = _new_world(scene)
    red, tree = background(world), world.node_tree
    red.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    blue = tree.nodes.new("ShaderNodeBackground")
    blue.inputs["Color"].default_value = (0.0, 0.0, 1.0, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.25
    tree.links.new(red.outputs[0], mix.inputs[1])
    tree.links.new(blue.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], _output(world).inputs["Surface"])


def a_cycles_output_beside_an_active_eevee_one(scene):
    world = _new_world(scene)
    red, tree = background(world), world.node_tree
    red.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    _output(world).target = "EEVEE"
    blue = tree.nodes.new("ShaderNodeBackground")
    blue.inputs["Color"].default_value = (0.0, 0.0, 1.0, 1.0)
    cycles = tree.nodes.new("ShaderNodeOutputWorld")
    cycles.target = "CYCLES"
    tree.links.new(blue.outputs[0], cycles.inputs["Surface"])


def an_output_fed_nothing(scene):
    world = _new_world(scene)
    background(world)
    for link in list(world.node_tree.links):
        world.node_tree.links.remove(link)


def no_world(scene):
    scene.world = None


WORLDS = [a_new_worlds_colour, a_background_at_strength_2, a_background_fed_by_rgb_and_value_nodes,
          an_emission_into_the_output, a_mix_of_two_backgrounds, a_cycles_output_beside_an_active_eevee_one,
          an_output_fed_nothing, no_world]


@pytest.mark.parametrize("make_world", WORLDS, ids=[f.__name__ for f in WORLDS])
def test_a_worlds_background_node_lights_the_scene_as_cycles_lights_it(make_world, engine, scene, tmp_path,
                                                                        load_pixels):
    """The plane lit by the world alone and the sky behind it, Lixel's against Cycles' (mean within 2 %)."""
    make_world(scene)
    cycles = _cycles(scene, tmp_path, load_pixels)
    lixel = _lixel(engine, scene)
    got = lixel["result"].combined
    for where in (PLANE, SKY):
        np.testing.assert_allclose(got[where][..., :3].mean(axis=(0, 1)), cycles[where][..., :3].mean(axis=(0, 1)),
                                   rtol=0.02, atol=2e-3)
    assert not any("World" in w for w in lixel["warnings"])


def test_a_textured_world_is_named_in_the_warnings(engine, world_light, scene):
    """A Sky Texture into the Background (Cycles, measured: the plane 12.1 / 10.5 / 9.2 in 5.0.1, the sun) is no one
    colour: Lixel lights with the world's viewport colour and says so, naming the world and the node."""
    world = _new_world(scene)
    world.color = (0.3, 0.2, 0.1)
    node = background(world)
    sky = world.node_tree.nodes.new("ShaderNodeTexSky")
    world.node_tree.links.new(sky.outputs[0], node.inputs["Color"])
    note = (f"World 'lixel_test world' lights with its Sky Texture node '{sky.name}', not one colour: Lixel lights "
            f"every surface with its viewport colour (0.3, 0.2, 0.1) instead; set World properties > Viewport Display "
            f"> Color to the sky's mean light, or render with Cycles for the sky itself")
    assert world_light(world) == ((0.30000001192092896, 0.20000000298023224, 0.10000000149011612), note)
    got = _lixel(engine, scene)
    assert f"Lixel: {note}" in got["warnings"]
    np.testing.assert_allclose(got["result"].combined[PLANE][..., :3], np.broadcast_to(
        ALBEDO * np.float32([0.3, 0.2, 0.1]), (12, 12, 3)), rtol=1e-5)


def test_an_environment_texture_is_named_too(world_light, scene):
    world = _new_world(scene)
    node = background(world)
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    world.node_tree.links.new(env.outputs[0], node.inputs["Color"])
    assert world_light(world).note.startswith(f"World 'lixel_test world' lights with its Environment Texture node "
                                          f"'{env.name}', not one colour")


def test_each_frame_of_an_animation_is_lit_by_that_frames_background(engine, scene, tmp_path):
    """The Background's colour keyed from (0.1, 0.1, 0.1) on frame 1 to (0.1, 0.2, 0.4) on frame 3: each frame of an
    animation render is lit with that frame's colour (the render's evaluated world, not the original's)."""
    scene.world = sky_world("lixel_test world", (0.1, 0.1, 0.1))
    colour = background(scene.world).inputs["Color"]
    for frame, value in ((1, (0.1, 0.1, 0.1, 1.0)), (3, (0.1, 0.2, 0.4, 1.0))):
        colour.default_value = value
        colour.keyframe_insert("default_value", frame=frame)
    scene.frame_set(1)
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.engine = "LIXEL"
    scene.render.filepath = str(tmp_path / "frame_")
    with engine.watch_renders(read={"combined"}) as got:
        assert bpy.ops.render.render(animation=True, scene=scene.name) == {"FINISHED"}
    plane = [g["result"].combined[PLANE][..., :3].mean(axis=(0, 1)) for g in got]
    np.testing.assert_allclose(plane[0], ALBEDO * np.float32([0.1, 0.1, 0.1]), rtol=1e-5)
    np.testing.assert_allclose(plane[2], ALBEDO * np.float32([0.1, 0.2, 0.4]), rtol=1e-5)
    assert np.all(plane[0][1:] < plane[1][1:]) and np.all(plane[1][1:] < plane[2][1:])


def test_what_lixel_cannot_evaluate_is_named_not_guessed(world_light, scene):
    """An RGB node into the Strength (Blender converts it by luminance), a Light Path trick, a muted Background:
    each is named, and the world's viewport colour lights instead."""
    world = _new_world(scene)
    node, tree = background(world), world.node_tree
    rgb = tree.nodes.new("ShaderNodeRGB")
    tree.links.new(rgb.outputs[0], node.inputs["Strength"])
    assert world_light(world).note.startswith(f"World 'lixel_test world' lights with its {rgb.bl_label} node '{rgb.name}'")
    tree.links.remove(node.inputs["Strength"].links[0])
    assert world_light(world).note is None
    node.mute = True
    assert world_light(world).note.startswith(f"World 'lixel_test world' lights with its Background node "
                                              f"'{node.name}' (muted)")
    node.mute = False
    path = tree.nodes.new("ShaderNodeLightPath")
    tree.links.new(path.outputs["Is Camera Ray"], node.inputs["Strength"])
    assert world_light(world).note.startswith(f"World 'lixel_test world' lights with its Light Path node")
    assert world_light(world).colour == tuple(float(c) for c in world.color)


def test_film_transparent_keeps_the_worlds_light_on_surfaces(engine, scene, tmp_path, load_pixels):
    """Film > Transparent (measured in Cycles, 4.2.23 and 5.0.1): the plane is still lit by the world, the sky behind
    it is transparent black."""
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)
    scene.render.film_transparent = True
    scene.render.image_settings.color_mode = "RGBA"
    cycles = _cycles(scene, tmp_path, load_pixels)
    got = _lixel(engine, scene)["result"].combined
    for where in (PLANE, SKY):
        np.testing.assert_allclose(got[where].mean(axis=(0, 1)), cycles[where].mean(axis=(0, 1)), rtol=0.02, atol=2e-3)
    np.testing.assert_allclose(got[SKY], 0.0)


def test_pictures_from_the_live_state_are_lit_by_the_world_as_f12_is(lixel, engine, scene):
    """``render_method.py``'s and the 3D view's pictures (``renders.render_state``, ``pip_images``) take the world's
    light and the spot's blend as F12 does. Before, they lit every scene with a fixed 0.05 grey and no blend: under a
    Background of (0.2, 0.3, 0.4) x 2 the sky and the shadowed plane came out 0.05 where F12 showed 0.4 / 0.6 / 0.8."""
    live = importlib.import_module(lixel.__name__ + ".addon.ui.live")
    renders = importlib.import_module(lixel.__name__ + ".addon.ui.renders")
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)
    spot = bpy.data.objects.new("lixel_test spot", bpy.data.lights.new("lixel_test spot", "SPOT"))
    spot.data.spot_size, spot.data.spot_blend, spot.data.energy = 1.2, 0.6, 500.0
    spot.location = (0.3, 0.2, 3.0)
    scene.collection.objects.link(spot)
    f12 = _lixel(engine, scene)["result"].combined
    depsgraph = bpy.context.evaluated_depsgraph_get()
    live.clear()
    st = live.update(scene, depsgraph)
    assert not st.error, st.error
    picture = renders.render_state(st, depsgraph, (SIZE, SIZE), read={"combined"}).combined
    np.testing.assert_allclose(picture[SKY][..., :3], np.broadcast_to(np.float32([0.4, 0.6, 0.8]), (4, 4, 3)),
                               rtol=1e-5)
    np.testing.assert_allclose(picture[..., :3], f12[..., :3], rtol=1e-4, atol=1e-5)
    pip = renders.pip_images(st, depsgraph, SIZE, want_map=False, want_scene=True)["scene"]
    np.testing.assert_allclose(pip[SKY][..., :3], picture[SKY][..., :3], rtol=1e-5)
    live.clear()
    bpy.data.objects.remove(spot)
