"""The world's Ray Visibility (World properties > Ray Visibility, ``world.cycles_visibility``) as Cycles renders it,
measured in 4.2.23 and 5.0.1 (addon/scene/world.py): Camera off shows black behind the scene and still lights it;
Diffuse off shows the sky and lights no (diffuse) surface. Before, Lixel ignored both: the sky showed behind the
scene and lit it either way."""
import bpy
import numpy as np
import pytest

from test_world_light import PLANE, SKY, _cycles, _lixel, scene  # noqa: F401 - the plane scene fixture
from worlds import sky_world


def _sun(scene):
    sun = bpy.data.objects.new("lixel_test sun", bpy.data.lights.new("lixel_test sun", "SUN"))
    sun.data.energy = 2.0
    scene.collection.objects.link(sun)
    return sun


@pytest.mark.parametrize("ray", ["camera", "diffuse"])
@pytest.mark.parametrize("with_sun", [False, True], ids=["world alone", "and a sun"])
def test_a_worlds_ray_visibility_is_followed_as_cycles_follows_it(ray, with_sun, engine, scene, tmp_path,
                                                                  load_pixels):
    """A Background (0.2, 0.3, 0.4) x 2 with one ray off: the plane and the sky behind it, Lixel's against Cycles'
    (mean within 2 %). Cycles: Camera off, sky (0, 0, 0) and the plane 0.32 / 0.48 / 0.64 lit by the world; Diffuse
    off, sky 0.4 / 0.6 / 0.8 and the plane black (0.51 grey with the sun)."""
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)
    setattr(scene.world.cycles_visibility, ray, False)
    if with_sun:
        sun = _sun(scene)
    cycles = _cycles(scene, tmp_path, load_pixels)
    got = _lixel(engine, scene)["result"].combined
    for where in (PLANE, SKY):
        np.testing.assert_allclose(got[where].mean(axis=(0, 1)), cycles[where].mean(axis=(0, 1)), rtol=0.02,
                                   atol=2e-3)
    if ray == "camera":
        np.testing.assert_array_equal(got[SKY], np.broadcast_to(np.float32([0, 0, 0, 1]), got[SKY].shape))
    if with_sun:
        bpy.data.objects.remove(sun)


def test_the_live_states_pictures_follow_it_too(lixel, engine, scene):
    """``render_method.py``'s and the 3D view's pictures (``renders.render_state``) take the same world as F12."""
    import importlib
    live = importlib.import_module(lixel.__name__ + ".addon.ui.live")
    renders = importlib.import_module(lixel.__name__ + ".addon.ui.renders")
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)
    scene.world.cycles_visibility.camera = False
    sun = _sun(scene)
    f12 = _lixel(engine, scene)["result"].combined
    depsgraph = bpy.context.evaluated_depsgraph_get()
    live.clear()
    st = live.update(scene, depsgraph)
    assert not st.error, st.error
    picture = renders.render_state(st, depsgraph, f12.shape[1::-1], read={"combined"}).combined
    np.testing.assert_allclose(picture[SKY][..., :3], 0.0)
    np.testing.assert_allclose(picture[..., :3], f12[..., :3], rtol=1e-4, atol=1e-5)
    live.clear()
    bpy.data.objects.remove(sun)


@pytest.mark.parametrize("switch", ["use_sky", "use_solid"], ids=["Environment", "Surfaces"])
def test_a_view_layers_filter_is_followed_as_cycles_follows_it(switch, engine, scene, tmp_path, load_pixels):
    """View Layer properties > Filter, one switch off, the Background (0.2, 0.3, 0.4) x 2: Cycles (measured in 4.2.23
    and 5.0.1) renders without Environment no world at all (the plane and the sky black) and without Surfaces the
    sky alone (0.4 / 0.6 / 0.8 over the plane too). Lixel lit the plane and showed the sky either way."""
    scene.world = sky_world("lixel_test world", (0.2, 0.3, 0.4), 2.0)
    layer = scene.view_layers[0]
    setattr(layer, switch, False)
    try:
        cycles = _cycles(scene, tmp_path, load_pixels)
        scene.render.engine = "LIXEL"
        with engine.watch_renders(read={"combined"}) as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    finally:
        setattr(layer, switch, True)
    for where in (PLANE, SKY):
        np.testing.assert_allclose(got[-1]["result"].combined[where].mean(axis=(0, 1)), cycles[where].mean(axis=(0, 1)),
                                   rtol=0.02, atol=2e-3)
    if switch == "use_solid":
        assert (f"Lixel: no shadows in this view (view layer '{layer.name}' has Surfaces off (View Layer properties > "
                f"Filter), so as in Cycles the frame shows only the world background)") in got[-1]["warnings"]
