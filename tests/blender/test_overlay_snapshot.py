"""scripts/overlay_snapshot.py draws the viewport overlays off-screen for any
scene, both ways of running a script, and refuses bad arguments; the observer
view frames the view frustum and B and names what it leaves out."""
import importlib
import subprocess

import numpy as np
import pytest

from test_scripts import MODES, blend, run  # noqa: F401 - the module fixture and helpers are shared


def _png(path):
    import bpy
    img = bpy.data.images.load(str(path), check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)


@pytest.mark.parametrize("mode", MODES)
def test_snapshots_of_a_scene_from_camera_and_observer(mode, blend, tmp_path):  # noqa: F811
    out = tmp_path / "snaps"
    r = run(mode, "overlay_snapshot.py", blend, "--output-dir", str(out), "--method", "lispsm", "--size", "16",
            "--width", "320")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    # nothing alarming on the terminal: Mesa's harmless EGL lines at GPU start and the overlay
    # shader's push-constant warning (its maps ride in a uniform block) stay off it
    assert "EGL Error" not in r.stdout + r.stderr and "Push constants" not in r.stdout + r.stderr, r.stdout + r.stderr
    camera, observer = _png(out / "overlay_camera.png"), _png(out / "overlay_observer.png")
    assert camera.shape[1] == 320 and observer.shape[:2] == (200, 320)
    # the camera sees the texel checker on the ground: many light and many dark texels
    light, dark = camera[..., 0] > 0.7, camera[..., 0] < 0.35   # over the grey backdrop at alpha 0.85
    assert light.mean() > 0.05 and dark.mean() > 0.05
    # the observer sees the view frustum's cyan lines and B's orange
    assert (np.abs(observer[..., :3] - (0.3, 0.8, 1.0)).max(axis=-1) < 0.12).sum() > 20
    assert ((observer[..., 0] > 0.6) & (observer[..., 2] < 0.35)).sum() > 8


@pytest.mark.parametrize("args,message", [
    (["--output-dir", "d", "--views", "camera,sideways"], "unknown sideways"),
    (["--output-dir", "d", "--observer-overlays", "body,bogus"], "unknown bogus"),
    (["--output-dir", "d", "--method", "nosuch"], "choose one of"),
])
def test_bad_arguments_are_refused(blend, args, message):  # noqa: F811
    r = run("module", "overlay_snapshot.py", blend, *args)
    assert r.returncode == 2 and message in r.stderr


def test_observer_frames_the_core_and_names_what_lies_beyond(lixel):
    snapshot = importlib.import_module(f"{lixel.__name__}.addon.ui.snapshot")

    class View:
        direction = np.array([0.0, 1.0, 0.0])
    box = np.array([[x, y, z] for x in (-1, 1) for y in (0, 10) for z in (0, 2)], dtype=float)
    far_view = np.concatenate([box[:4], box[4:] * [20, 20, 1]])          # a far plane 200 m away
    geometry = {"view_corners": far_view, "body_edges": np.stack([box[::2], box[1::2]], axis=1),
                "light_lines": np.array([[[0, 0, 0], [0, 0, 500.0]]]), "warp_lines": np.zeros((0, 2, 3)),
                "points": {"projection_centre": np.array([0, -1.0, 1])}}
    vp, notes = snapshot.observer_view_projection(geometry, View(), 1.6)
    clip = np.c_[box, np.ones(len(box))] @ vp.T
    ndc = clip[:, :3] / clip[:, 3:]
    assert (clip[:, 3] > 0).all() and (np.abs(ndc) <= 1).all()        # B is in the picture
    assert np.ptp(ndc[:, :2], axis=0).max() > 1.5                      # and fills it
    assert [n.split(" reach")[0] for n in notes] == ["camera's view frustum", "light frusta"]
    assert notes[0].startswith("camera's view frustum reaches ") and notes[1].startswith("light frusta reach ")


def test_operator_saves_camera_and_observer_snapshots(lixel, tmp_path):
    import bpy
    from ui_scenes import active_scene
    with active_scene("lixel_snapshot_op") as scene:
        scene.lixel.show_texels = True
        assert bpy.ops.lixel.overlay_snapshot(directory=str(tmp_path), width=160) == {"FINISHED"}
        assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay_camera.png", "overlay_observer.png"]
        camera = _png(tmp_path / "overlay_camera.png")
        assert camera.shape[1] == 160 and (camera[..., 0] > 0.7).any() and (camera[..., 0] < 0.35).any()
        scene.lixel.show_texels = False


def test_a_second_snapshot_keeps_the_first(lixel, tmp_path):
    """Saving snapshots twice into one folder (of two methods, say) writes the second set beside the first,
    numbered, and says which files it wrote: the first set's pictures are the user's and stay as they were."""
    import bpy
    from ui_scenes import active_scene
    with active_scene("lixel_snapshot_twice"):
        assert bpy.ops.lixel.overlay_snapshot(directory=str(tmp_path), width=96) == {"FINISHED"}
        first = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
        (tmp_path / "overlay_observer.png").write_bytes(b"the user's own picture")
        assert bpy.ops.lixel.overlay_snapshot(directory=str(tmp_path), width=96) == {"FINISHED"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay_camera.png", "overlay_camera_2.png",
                                                          "overlay_observer.png", "overlay_observer_2.png"]
    assert (tmp_path / "overlay_camera.png").read_bytes() == first["overlay_camera.png"]
    assert (tmp_path / "overlay_observer.png").read_bytes() == b"the user's own picture"


def test_operator_without_a_folder_or_camera_says_so(lixel, tmp_path):
    import bpy
    from ui_scenes import active_scene
    with active_scene("lixel_snapshot_nofolder") as scene:
        with pytest.raises(RuntimeError, match="choose a folder"):
            bpy.ops.lixel.overlay_snapshot(directory="")
    with active_scene("lixel_snapshot_nocam", camera=False):
        with pytest.raises(RuntimeError, match="camera"):
            bpy.ops.lixel.overlay_snapshot(directory=str(tmp_path))
    assert not list(tmp_path.iterdir())


def test_operator_names_what_the_observer_picture_leaves_out(lixel, tmp_path, capfd):
    """The operator's observer picture leaves out what lies far beyond B (a far clip plane 500 m away): the script
    named it ("note: camera's view frustum reaches ... beyond the picture"), the operator drew the lines running out
    of the picture and said nothing."""
    import bpy
    from ui_scenes import active_scene
    with active_scene("lixel_snapshot_notes") as scene:
        scene.camera.data.clip_end = 500.0
        assert bpy.ops.lixel.overlay_snapshot(directory=str(tmp_path), width=96) == {"FINISHED"}
    out = capfd.readouterr().out
    assert "Lixel: saved overlay_camera.png, overlay_observer.png in " in out
    assert "the observer's picture leaves out: camera's view frustum reaches " in out and "beyond the picture" in out
