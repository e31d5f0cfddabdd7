"""The overlay draw code runs on a real GPU context (llvmpipe, offscreen) and
draws what it should: B in its colour, the frusta's lines, the texel-parity
checker (both parities, about half each) and the footprint heatmap on the
receivers; the picture-in-picture images have the right sizes."""
import importlib
import os

import bpy
import mathutils
import numpy as np
import pytest

from ui_scenes import active_scene

W, H = 96, 64
DEBUG_PNG = os.environ.get("LIXEL_DEBUG_PNG")


@pytest.fixture(scope="module")
def m(lixel):
    class M:
        pass
    ns = M()
    for name in ("live", "overlays", "renders", "snapshot"):
        setattr(ns, name, importlib.import_module(f"{lixel.__name__}.addon.ui.{name}"))
    ns.geometry = importlib.import_module(f"{lixel.__name__}.addon.warp.geometry")
    importlib.import_module(f"{lixel.__name__}.addon.gpu.context").ensure_gpu_context()
    return ns


def observer(m):
    """A camera above and to the side of the test scene, looking at its centre."""
    world_to_eye = m.geometry.look_along(np.array([9.0, -10.0, 9.0]), np.array([-9.0, 10.0, -9.0]),
                                         np.array([0.0, 0.0, 1.0]))
    return m.geometry.perspective_matrix(np.radians(50), W / H, 0.5, 100.0) @ world_to_eye


def draw(m, scene, st, view_projection, **flags):
    import gpu
    import mathutils
    props = scene.lixel
    for name in ("show_body", "show_frusta", "show_warp", "show_texels", "show_footprint"):
        setattr(props, name, flags.get(name, False))
    offscreen = gpu.types.GPUOffScreen(W, H)
    try:
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_identity()
                gpu.matrix.load_projection_matrix(mathutils.Matrix(view_projection.tolist()))
                m.overlays.draw_scene_overlays(scene, st, props, view_projection)
            buf = fb.read_color(0, 0, W, H, 4, 0, "FLOAT")
        return np.array(buf.to_list(), dtype=np.float32).reshape(H, W, 4)
    finally:
        offscreen.free()


def near(img, rgb, tol=0.08):
    return np.all(np.abs(img[..., :3] - np.asarray(rgb)) < tol, axis=-1) & (img[..., 3] > 0)


def test_body_and_frusta_are_drawn(m):
    with active_scene("lixel_draw") as scene:
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        vp = observer(m)
        empty = draw(m, scene, st, vp)
        assert not (empty[..., 3] > 0).any()
        body = draw(m, scene, st, vp, show_body=True)
        covered = body[..., 3] > 0
        assert 0.02 < covered.mean() < 0.98
        assert (body[covered][:, 0] > body[covered][:, 2]).all()  # orange: red over blue
        frusta = draw(m, scene, st, vp, show_frusta=True)
        assert near(frusta, m.overlays.COLOURS["light"][:3], 0.1).sum() > 20
        assert near(frusta, m.overlays.COLOURS["view"][:3], 0.1).sum() > 20


def test_texel_checker_and_heatmap_on_receivers(m):
    with active_scene("lixel_draw_texels") as scene:
        scene.lixel.initialised = True
        scene.lixel.method = "uniform"
        scene.lixel.shadow_map_size = (16, 16)  # texels much larger than pixels (16: the smallest map)
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        vp = observer(m)
        img = draw(m, scene, st, vp, show_texels=True)
        if DEBUG_PNG:
            m.renders.save_image(img, DEBUG_PNG)
        drawn = img[..., 3] > 0
        assert drawn.mean() > 0.1
        # drawn at alpha 0.85 over black: a light texel reads ~0.8, a dark one ~0.1; "no map" has alpha ~0.2
        served = img[..., 3] > 0.5
        light = served & (img[..., 0] > 0.5)
        dark = served & (img[..., 0] < 0.3)
        assert served.sum() > 50 and (light | dark).sum() == served.sum()
        assert 0.25 < dark.sum() / served.sum() < 0.75  # a checker: both parities, about as often
        heat = draw(m, scene, st, vp, show_footprint=True)
        hot = heat[heat[..., 3] > 0.5][:, :3]
        assert len(hot) == served.sum()  # the same receivers are served
        # 8x8 texels on a ~10 m ground seen over ~96 px: each texel spans several pixels -> the red end
        assert (hot[:, 0] > hot[:, 2]).mean() > 0.9
        scene.lixel.shadow_map_size = (4096, 4096)  # now texels are far smaller than pixels -> the blue end
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        fine = draw(m, scene, st, vp, show_footprint=True)
        cold = fine[fine[..., 3] > 0.5][:, :3]
        assert (cold[:, 2] > cold[:, 0]).mean() > 0.9


def test_the_texel_checker_and_heatmap_keep_their_precision_far_from_the_origin(m):
    """The scene and the observer moved 1000 km away draw the checker and the heatmap they draw at the origin: the
    receivers are drawn relative to their centre, as the render draws the scene (``batches.drawing_origin``). In
    world coordinates float32 steps there are 6 cm: the heatmap's screen derivatives turned to noise (red, green
    and blue speckles all over the ground) and the checker's texels frayed; so did the overlay snapshot's grey
    backdrop, which the overlays are depth-tested against."""
    with active_scene("lixel_draw_far") as scene:
        scene.lixel.initialised = True
        scene.lixel.method = "uniform"
        scene.lixel.shadow_map_size = (64, 64)
        vp = observer(m)
        drawn = {}
        for offset in (0.0, 1.0e6):
            for ob in scene.objects:
                ob.location.x += offset
            shift = np.eye(4)
            shift[0, 3] = -offset
            st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
            assert st.ok, st.error
            drawn[offset] = [draw(m, scene, st, vp @ shift, **{flag: True}) for flag in ("show_texels",
                                                                                         "show_footprint")]
            drawn[offset] += [m.snapshot.draw_snapshot(scene, st, m.snapshot.OverlayFlags.of([flag]), vp @ shift,
                                                       (W, H)) for flag in ("texels", "footprint")]   # (a backdrop)
        for near_origin, far in zip(drawn[0.0], drawn[1.0e6]):
            opaque = near_origin[..., 3].min() == 1.0          # (the snapshot's background)
            served = np.abs(near_origin - m.snapshot.BACKGROUND).max(axis=-1) > 0.1 if opaque else \
                near_origin[..., 3] > 0.5
            assert served.mean() > 0.1
            differ = np.abs(near_origin - far).max(axis=-1) > 0.1
            assert differ[served].mean() < 0.01   # (0 here; 0.42 and 0.04 drawn in world coordinates)


def test_picture_in_picture_images(m):
    with active_scene("lixel_draw_pip") as scene:
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        images = m.renders.pip_images(st, bpy.context.evaluated_depsgraph_get(), 40, True, True)
        assert images["scene"].shape == (22, 40, 4)  # 640x360 fitted to 40 px
        assert images["map"].shape[2] == 4 and max(images["map"].shape[:2]) <= 40
        d = m.renders.depth_to_rgba(np.array([[0.2, 0.6], [1.0, 0.4]], dtype=np.float32))
        assert d[0, 0, 0] > d[1, 1, 0] > d[0, 1, 0]  # nearer the light = brighter
        np.testing.assert_allclose(d[1, 0], (0.05, 0.05, 0.15, 1.0))


def test_picture_in_picture_is_drawn_bottom_right(m):
    import gpu
    import mathutils
    with active_scene("lixel_draw_pip2") as scene:
        props = scene.lixel
        props.map_pip_size = 64
        props.show_map, props.show_shadowed = True, False
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        w, h = 200, 140
        offscreen = gpu.types.GPUOffScreen(w, h)
        try:
            with offscreen.bind():
                fb = gpu.state.active_framebuffer_get()
                fb.clear(color=(0.0, 0.0, 0.0, 0.0))
                with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                    gpu.matrix.load_identity()
                    ortho = m.geometry.ortho_matrix(0, w, 0, h, -1, 1)  # pixel space, as in POST_PIXEL
                    gpu.matrix.load_projection_matrix(mathutils.Matrix(ortho.tolist()))
                    note = m.overlays._draw_gpu_overlays(scene, st, props)
                img = np.array(fb.read_color(0, 0, w, h, 4, 0, "FLOAT").to_list(), dtype=np.float32).reshape(h, w, 4)
        finally:
            offscreen.free()
        assert note == ""
        drawn = img[..., 3] > 0
        ys, xs = np.nonzero(drawn)
        # a 64-pixel map, 20 px from the right edge, PIP_BOTTOM px from the bottom
        assert xs.max() == w - 21 and xs.min() == w - 20 - 64
        assert ys.min() == m.overlays.PIP_BOTTOM and ys.max() == m.overlays.PIP_BOTTOM + 63
        assert img[drawn][:, :3].std() > 0.05  # the map's picture, not a flat colour


def test_the_overlays_of_a_3d_view_with_a_local_camera_show_that_camera(m):
    """View sidebar > View > Local Camera: F12 in that 3D view renders its camera (test_render_engine), and the
    overlays drawn there, the operators run from it and the live updates now follow that camera too, not the
    scene's. The module's own window's 3D view stands in for the user's."""
    with active_scene("lixel_local_camera") as scene:
        scene.lixel.show_body = True
        side = bpy.data.objects.new("lixel_local_camera side", bpy.data.cameras.new("lixel_local_camera side"))
        scene.collection.objects.link(side)
        side.location = (-6, -7, 5)
        side.rotation_euler = (mathutils.Vector((0, 0, 0)) - side.location).to_track_quat("-Z", "Y").to_euler()
        bpy.context.view_layer.update()
        win = bpy.context.window
        area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
        space, region = area.spaces.active, next(r for r in area.regions if r.type == "WINDOW")
        was = space.use_local_camera, space.camera

        def position(st):
            return tuple(np.round(st.view.camera_to_world[:3, 3], 5))

        try:
            space.use_local_camera, space.camera = True, side
            with bpy.context.temp_override(window=win, area=area, region=region, space_data=space):
                _, st = m.overlays._scene_state()                          # what the view's draw callbacks draw
                assert st.ok and position(st) == (-6, -7, 5)
                side.location.x = -5                                        # a live update follows the local camera
                bpy.context.view_layer.update()
                m.overlays.on_depsgraph_update(scene, bpy.context.evaluated_depsgraph_get())
                assert position(m.live.state(scene)) == (-5, -7, 5)
                assert bpy.ops.lixel.refresh() == {"FINISHED"}             # as does an operator run from the view
                assert position(m.live.state(scene)) == (-5, -7, 5)
                space.use_local_camera = False
                _, st = m.overlays._scene_state()
                assert position(st) == tuple(np.round(scene.camera.location, 5))
        finally:
            space.use_local_camera, space.camera = was
            scene.lixel.show_body = False
            m.overlays.sync_handlers()


def test_a_picture_in_picture_that_failed_is_not_rendered_again_on_every_redraw(m, monkeypatch):
    """A refused render (the memory guard, say) shows its message in the status line; the viewport redraws many
    times a second, and each redraw tried the whole render again. Tried again once what is shown changes."""
    with active_scene("lixel_draw_pip_fails") as scene:
        props = scene.lixel
        props.map_pip_size = 64
        props.show_map, props.show_shadowed = True, False
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        tries, warp_error = [], importlib.import_module(m.geometry.__name__.rsplit(".", 1)[0] + ".types").WarpError

        def refused(*args, **kwargs):
            tries.append(args)
            raise warp_error("8 shadow maps of 16384x16384 texels would take 8.0 GiB of GPU memory")
        monkeypatch.setattr(m.renders, "pip_textures", refused)
        notes = [m.overlays._draw_gpu_overlays(scene, st, props) for _ in range(3)]
        assert len(tries) == 1
        assert all("16384x16384" in note for note in notes)
        props.map_pip_size = 96
        assert "16384x16384" in m.overlays._draw_gpu_overlays(scene, st, props)
        assert len(tries) == 2


def test_the_picture_in_picture_keeps_no_more_gpu_memory_than_a_frame_does(m, monkeypatch):
    """The viewport's pictures drew into the scene's own pool and kept all of it until the next render, the shadow
    maps too: a setup under the memory guard (8 maps of 8192², 2 GiB) stayed held per scene after the pictures were
    drawn, and after they were switched off; F12's frames keep at most ``TargetPool.KEEP_BYTES``. The pictures'
    pool is trimmed as a frame's is, and the pictures still draw."""
    targets = importlib.import_module(m.live.__name__.rsplit(".", 2)[0] + ".gpu.targets")
    monkeypatch.setattr(targets.TargetPool, "KEEP_BYTES", 2 ** 20)     # a 1024² depth map takes 4 MiB
    with active_scene("lixel_draw_pip_memory") as scene:
        props = scene.lixel
        props.map_pip_size = 64
        props.shadow_map_size = (1024, 1024)
        props.show_map, props.show_shadowed = True, True
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert not st.error, st.error
        assert m.overlays._draw_gpu_overlays(scene, st, props) == ""
        _, textures, pool = m.overlays._pip[m.live.scene_key(scene)]
        assert pool.bytes <= 2 ** 20, pool.bytes
        assert sorted(textures) == ["map", "scene"] and max(t.width for t in textures.values()) == 64
        assert m.overlays._draw_gpu_overlays(scene, st, props) == ""       # drawn again from what was kept
