"""The bad-input audit's catalogue (issue 14), run through the render engine and
every operator, kept as a test so it stays true:

* no entry point prints a traceback, and no bug reaches the guard ("unexpected
  error"): every failure is a clear message naming the object and what to do;
* a case Lixel cannot render is refused with its own message, by the engine and
  by every operator that needs a setup;
* a case Lixel renders renders right (checked against what the image must be:
  Workbench's coverage, the same scene at the origin, the spot an area light
  becomes, ...): no silent wrong image;
* no datablock of the user's changes (the texel grid, which the user asks to put
  on their mesh, is taken off again and must leave it exactly as it was).

The CLI's malformed configs are in tests/warp/test_cli.py (MALFORMED); a few of
the audit's own are repeated at the end.
"""
from __future__ import annotations

import contextlib
import ctypes
import importlib
import math
import os
import re
import sys
import tempfile
from dataclasses import dataclass
from typing import Callable, Optional

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene, cube_mesh, digest

SCENE = "catalogue"
W, H = 64, 36
ENTRY_POINTS = ("render", "refresh", "toggle_overlay", "bake_debug", "export_json", "compare", "sync_matrices",
                "frustum_add", "texel_grid_add", "overlay_snapshot", "planes_from_selection", "reset_settings")
NEEDS_SETUP = ("render", "refresh", "toggle_overlay", "bake_debug", "export_json", "compare", "sync_matrices",
               "frustum_add", "texel_grid_add", "overlay_snapshot")
"""Entry points that describe the scene and compute (the others only edit settings)."""
LIXEL_NAMES = ("Lixel B", "Lixel View Frustum", "Lixel Light Frustum 0 (main)", "Lixel Light Matrices",
               "Lixel Frustum (map 0)", "Lixel Debug", "Lixel Texel Grid", "Lixel Frustum From Matrix",
               "Lixel Comparison")


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    m.engine = importlib.import_module(f"{lixel.__name__}.addon.render.engine")
    m.live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    m.owned = importlib.import_module(f"{lixel.__name__}.addon.scene.owned")
    return m


# --- the cases ------------------------------------------------------------------------------------------------

def _light(sc):
    return sc.objects[f"{SCENE} light"]


def _remove(sc, *names):
    for n in names:
        bpy.data.objects.remove(sc.objects[f"{SCENE} {n}"])


def _no_faces(sc):
    _remove(sc, "ground", "cube")
    me = bpy.data.meshes.new("catalogue edges")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1), (1, 2)], [])
    sc.collection.objects.link(bpy.data.objects.new("catalogue edges", me))


def _far_away(sc):
    for ob in sc.objects:
        ob.location.x += 1e7
        ob.location.y -= 1e7


def _light_at_camera(sc):
    _light(sc).data.type = "POINT"
    _light(sc).location = sc.camera.location


def _ortho(sc):
    sc.camera.data.type = "ORTHO"
    sc.camera.data.ortho_scale = 12.0


def _lixel_light_elsewhere(sc):
    """The light chosen as the Lixel light is moved to another scene: Blender lights nothing with it here."""
    sc.lixel.light = _light(sc)
    elsewhere = bpy.data.scenes.get("catalogue elsewhere") or bpy.data.scenes.new("catalogue elsewhere")
    sc.collection.objects.unlink(_light(sc))
    elsewhere.collection.objects.link(bpy.data.objects[f"{SCENE} light"])


def _collisions(sc):
    """A datablock of the user's under every name Lixel uses, kept by a fake user."""
    for name in LIXEL_NAMES:
        me = cube_mesh(name, half=0.3)
        me.use_fake_user = True
        ob = bpy.data.objects.new(name, me)
        ob.use_fake_user = True
    coll = bpy.data.collections.get("Lixel Debug") or bpy.data.collections.new("Lixel Debug")
    coll.use_fake_user = True
    for kind in ("GeometryNodeTree",):
        for name in ("Lixel Texel Grid", "Lixel Frustum From Matrix"):
            bpy.data.node_groups.new(name, kind).use_fake_user = True
    bpy.data.materials.new("Lixel Texel Grid").use_fake_user = True
    bpy.data.texts.new("Lixel Comparison").write("the user's notes\n")
    bpy.data.images.new("Lixel Comparison", 4, 4).use_fake_user = True


@dataclass
class Case:
    change: Callable
    refused: Optional[str] = None
    """What every entry point that needs a setup must say (regex); None: Lixel renders it."""
    engine_refused: Optional[str] = None
    """What the engine says, when it differs (Blender's own check comes first); "": the engine renders it."""
    check: Optional[str] = None
    """Name of the check of the engine's image (below)."""


CASES = {
    "no_camera": Case(lambda sc: bpy.data.objects.remove(sc.camera), r"Scene 'catalogue' has no camera: add a camera",
                      engine_refused=r"Cannot render, no camera"),
    "no_light": Case(lambda sc: bpy.data.objects.remove(_light(sc)),
                     r"Scene 'catalogue' has no light: add a Sun, Point, Spot or Area light",
                     engine_refused="", check="world_light_only"),
    "area_light": Case(lambda sc: setattr(_light(sc).data, "type", "AREA"), check="area_is_its_spot"),
    "zero_strength_light": Case(lambda sc: setattr(_light(sc).data, "energy", 0.0), check="no_direct_light"),
    "nan_camera": Case(lambda sc: setattr(sc.camera, "location", (float("nan"), 0, 4)),
                       r"Camera 'catalogue camera' has a non-finite transform \(NaN or infinity"),
    "zero_scale_camera": Case(lambda sc: setattr(sc.camera, "scale", (0, 0, 0)),
                              r"Camera 'catalogue camera' has zero scale on its X, Y, Z axes.*set its scale to 1"),
    "nan_light": Case(lambda sc: setattr(_light(sc), "location", (3, float("nan"), 8)),
                      r"Light 'catalogue light' has a non-finite transform \(NaN or infinity"),
    "zero_scale_light": Case(lambda sc: setattr(_light(sc), "scale", (0, 0, 0)),
                             r"Light 'catalogue light' has zero scale on its Z axis.*set its scale to 1"),
    "nan_vertex": Case(lambda sc: sc.objects[f"{SCENE} cube"].data.vertices[0].co.__setitem__(0, float("nan")),
                       r"Object 'catalogue cube' has vertices with non-finite coordinates \(NaN or infinity\): fix"),
    "infinite_vertex": Case(lambda sc: sc.objects[f"{SCENE} ground"].data.vertices[2].co.__setitem__(2, float("inf")),
                            r"Object 'catalogue ground' has vertices with non-finite coordinates \(NaN or infinity\)"),
    "empty_scene": Case(lambda sc: [bpy.data.objects.remove(ob) for ob in list(sc.objects)],
                        r"Scene 'catalogue' has no camera", engine_refused=r"Cannot render, no camera"),
    "mesh_with_no_faces": Case(_no_faces, r"Scene 'catalogue' has no visible faces \(no mesh, curve or text object with faces\): add",
                               engine_refused="", check="world_only"),
    "map_size_0": Case(lambda sc: setattr(sc.lixel, "shadow_map_size", (0, 0)),
                       r"Scene 'catalogue' has a shadow map size of 0x0, out of range: use 16\.\.16384"),
    "map_size_16384": Case(lambda sc: setattr(sc.lixel, "shadow_map_size", (16384, 16384)), check="as_at_2048"),
    "map_size_65536": Case(lambda sc: setattr(sc.lixel, "shadow_map_size", (65536, 65536)),
                           r"Scene 'catalogue' has a shadow map size of 65536x65536, out of range: use 16\.\.16384"),
    "orthographic_camera": Case(_ortho, check="covers_what_workbench_covers"),
    "near_1e-6_far_1e9": Case(lambda sc: (setattr(sc.camera.data, "clip_start", 1e-6),
                                          setattr(sc.camera.data, "clip_end", 1e9)),
                              r"Camera 'catalogue camera' clips from 1 µm to 1e\+09 m, a range of 1:1e\+15, beyond what "
                              r"32-bit float depth resolves .*raise the clip start"),
    "orthographic_near_1e-6_far_100": Case(lambda sc: (_ortho(sc), setattr(sc.camera.data, "clip_start", 1e-6),
                                                       setattr(sc.camera.data, "clip_end", 100.0)),
                                           check="covers_what_workbench_covers"),  # linear depth: any ratio resolves
    "light_at_camera": Case(_light_at_camera, check="no_shadow_seen"),
    "scene_1e7_from_origin": Case(_far_away, check="as_at_the_origin"),
    "name_collisions": Case(_collisions, check="has_shadows"),
    "lixel_light_in_another_scene": Case(_lixel_light_elsewhere, r"The Lixel light 'catalogue light' is not among "
                                                                 r"the lights scene 'catalogue' shows .*choose another",
                                                 engine_refused="", check="world_light_only"),
}


# --- running an entry point -------------------------------------------------------------------------------------

@contextlib.contextmanager
def captured():
    """Everything written to file descriptors 1 and 2 (Blender's C code included)."""
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile(mode="w+b") as f:
        saved = os.dup(1), os.dup(2)
        os.dup2(f.fileno(), 1)
        os.dup2(f.fileno(), 2)
        out = []
        try:
            yield out
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            ctypes.CDLL(None).fflush(None)  # C stdio buffers what Blender prints when stdout is a file
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            f.seek(0)
            out.append(f.read().decode(errors="replace"))


def render(mods, scene):
    """(finished, message or the warnings, RenderResult or None) of an engine render of ``scene``."""
    with mods.engine.watch_renders(read={"covered", "shadow_mask", "combined"}) as got:
        try:
            bpy.ops.render.render(scene=scene.name)
        except RuntimeError as exc:
            return False, str(exc), None
    return bool(got), " / ".join(got[-1]["warnings"]) if got else "", got[-1]["result"] if got else None


def run(mods, entry, scene, tmp_path):
    """(finished, message, result) of one entry point on ``scene``."""
    if entry == "render":
        return render(mods, scene)
    kw = {"export_json": {"filepath": str(tmp_path / "setup.json")}, "compare": {"longest_side": 24},
          "toggle_overlay": {"overlay": "show_body"},
          "overlay_snapshot": {"directory": str(tmp_path / "snapshots"), "width": 64}}.get(entry, {})
    try:
        return getattr(bpy.ops.lixel, entry)(**kw) == {"FINISHED"}, "", None
    except RuntimeError as exc:
        return False, str(exc), None


def user_data() -> dict:
    """Digest of every datablock Lixel did not make (the scene's own Lixel settings excepted)."""
    out = {}
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.cameras, bpy.data.lights, bpy.data.materials,
                 bpy.data.node_groups, bpy.data.collections, bpy.data.texts, bpy.data.images):
        for idb in coll:
            if "lixel_made" not in idb.keys():
                out[(type(idb).__name__, idb.name)] = digest(idb)
    return out


def _clean_lixel_data(mods):
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.collections, bpy.data.node_groups, bpy.data.materials,
                 bpy.data.texts, bpy.data.images):
        for idb in [i for i in coll if mods.owned.is_lixel_made(i) or i.use_fake_user and i.name.startswith("Lixel")]:
            coll.remove(idb)
    text = bpy.data.texts.get("Lixel Comparison")
    if text is not None:
        bpy.data.texts.remove(text)


@pytest.fixture
def catalogue_scene(lixel, mods):
    with active_scene(SCENE) as scene:
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = W, H, 100
        scene.render.engine = "LIXEL"
        scene.lixel.initialised = True
        scene.lixel.shadow_map_size = (1024, 1024)
        for ob in scene.objects:
            ob.select_set(ob.type == "MESH")
        bpy.context.view_layer.objects.active = scene.objects[f"{SCENE} cube"]
        yield scene
        scene.lixel.show_body = False
        _clean_lixel_data(mods)
        elsewhere = bpy.data.scenes.get("catalogue elsewhere")
        if elsewhere is not None:
            bpy.data.batch_remove([*elsewhere.objects, *(ob.data for ob in elsewhere.objects)])
            bpy.data.scenes.remove(elsewhere)
    mods.live.clear()


@pytest.mark.parametrize("entry", ENTRY_POINTS)
@pytest.mark.parametrize("name", list(CASES))
def test_the_audit_catalogue(mods, catalogue_scene, tmp_path, name, entry):
    case, scene = CASES[name], catalogue_scene
    case.change(scene)
    bpy.context.view_layer.update()
    before = user_data()
    with captured() as out:
        finished, message, result = run(mods, entry, scene, tmp_path)
        if entry == "texel_grid_add" and finished:
            assert bpy.ops.lixel.texel_grid_add(remove=True) == {"FINISHED"}
    printed = out[0]
    assert "Traceback" not in printed + message, (message, printed[-3000:])
    assert "unexpected error" not in printed + message, printed[-3000:]
    refused = case.engine_refused if entry == "render" and case.engine_refused is not None else case.refused
    if refused and entry == "texel_grid_add":
        refused = f"{refused}|no mesh selected"  # it checks the selection first
    if refused and entry in NEEDS_SETUP:
        assert not finished and re.search(refused, message), (message, printed[-1500:])
    elif entry in NEEDS_SETUP:
        assert finished, message
    else:  # settings only: done, or a clear word on what is missing (e.g. no mesh selected)
        assert finished or message.startswith("Error: Lixel: "), message
    assert user_data() == before, "a datablock of the user's changed"
    if entry == "render" and case.check:
        CHECKS[case.check](mods, scene, result, message, tmp_path)


LIVE_CASES = [n for n, c in CASES.items() if c.refused and n not in ("empty_scene",)]


@pytest.mark.parametrize("name", LIVE_CASES)
def test_live_updates_after_a_case_say_why_and_print_nothing(mods, catalogue_scene, name):
    """With live update on (the default), the scene was computed, then the user
    makes it bad: every depsgraph update after that keeps the message in the
    live state (the panel and the overlay's status line show it), never a
    traceback from the handler."""
    scene = catalogue_scene
    assert scene.lixel.live_update
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    with captured() as out:
        CASES[name].change(scene)
        bpy.context.view_layer.update()
        scene.frame_set(scene.frame_current)  # and one more update
    assert "Traceback" not in out[0], out[0][-3000:]
    st = mods.live.state(scene)
    assert st is not None and re.search(CASES[name].refused, st.error), st.error


# --- what a rendered image must be ------------------------------------------------------------------------------

def _mismatch(a, b) -> float:
    return float(np.mean(np.asarray(a) != np.asarray(b)))


def area_is_its_spot(mods, scene, result, warnings, _tmp):
    assert "is shadowed as a spot light at its centre" in warnings
    light = _light(scene).data
    spread = min(light.spread, math.radians(179.0))
    light.type = "SPOT"
    scene.objects[f"{SCENE} light"].data.spot_size = spread
    scene.objects[f"{SCENE} light"].data.spot_blend = 0.0
    ok, msg, spot = render(mods, scene)
    assert ok, msg
    assert _mismatch(result.shadow_mask > 0.5, spot.shadow_mask > 0.5) < 0.005


def no_direct_light(mods, scene, result, warnings, _tmp):
    assert "has a strength of 0: it lights nothing" in warnings
    _light(scene).data.energy = 3.0
    ok, msg, lit = render(mods, scene)
    assert ok, msg
    shadowed = lit.covered & (lit.shadow_mask > 0.999)
    assert shadowed.any() and (lit.covered & (lit.shadow_mask < 0.5)).any()
    # in full shadow the lit scene shows only what the dark one shows everywhere
    np.testing.assert_allclose(result.combined[shadowed][:, :3], lit.combined[shadowed][:, :3], atol=1e-5)
    assert result.combined[lit.covered][:, :3].sum() < lit.combined[lit.covered][:, :3].sum()


def as_at_2048(mods, scene, result, _warnings, _tmp):
    scene.lixel.shadow_map_size = (2048, 2048)
    ok, msg, ref = render(mods, scene)
    assert ok, msg
    assert (ref.shadow_mask[ref.covered] > 0.5).mean() > 0.01, "the reference shows a shadow"
    assert _mismatch(result.shadow_mask > 0.5, ref.shadow_mask > 0.5) < 0.02


def covers_what_workbench_covers(mods, scene, result, _warnings, tmp_path):
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "wb.png")
    bpy.ops.render.render(write_still=True, scene=scene.name)
    img = bpy.data.images.load(str(tmp_path / "wb.png"))
    try:
        px = np.empty(W * H * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    wb = px.reshape(H, W, 4)[..., 3] > 0.5
    assert 0.1 < wb.mean() and _mismatch(wb, result.covered) < 0.03


def no_shadow_seen(_mods, _scene, result, _warnings, _tmp):
    """A light at the eye lights everything the eye sees."""
    assert result.covered.mean() > 0.3
    assert (result.shadow_mask[result.covered] > 0.5).mean() < 0.01


def as_at_the_origin(mods, scene, result, _warnings, _tmp):
    for ob in scene.objects:
        ob.location.x -= 1e7
        ob.location.y += 1e7
    bpy.context.view_layer.update()
    ok, msg, ref = render(mods, scene)
    assert ok, msg
    assert (ref.shadow_mask[ref.covered] > 0.5).mean() > 0.01, "the reference shows a shadow"
    assert _mismatch(result.covered, ref.covered) < 0.01
    assert _mismatch(result.shadow_mask > 0.5, ref.shadow_mask > 0.5) < 0.01


def world_only(_mods, _scene, result, warnings, _tmp):
    """Nothing to see: the world background, as Blender's engines render it (an animation goes on past it)."""
    assert "so the frame shows only the world background" in warnings
    assert not result.covered.any() and not result.shadow_mask.any()


def world_light_only(_mods, _scene, result, warnings, _tmp):
    """No light shown: the world's light alone, unshadowed, as Blender's engines light it (an animation goes on)."""
    assert "the frame is lit by the world alone" in warnings
    assert result.covered.mean() > 0.3 and not result.shadow_mask.any()


def has_shadows(_mods, _scene, result, _warnings, _tmp):
    assert result.covered.mean() > 0.3 and (result.shadow_mask[result.covered] > 0.5).mean() > 0.01


CHECKS = {f.__name__: f for f in (area_is_its_spot, no_direct_light, as_at_2048, covers_what_workbench_covers,
                                  no_shadow_seen, as_at_the_origin, has_shadows, world_only,
                                  world_light_only)}
assert {c.check for c in CASES.values() if c.check} <= set(CHECKS)


# --- the CLI ----------------------------------------------------------------------------------------------------

CLI_CASES = {
    "unknown key light.energy": (lambda c: c["light"].__setitem__("energy", 3.0), 2, "light.energy: unknown key"),
    "aspect 1e-300": (lambda c: c["camera"].__setitem__("aspect", 1e-300), 2, "camera.aspect: must be between"),
    "matrix 1e300": (lambda c: c["camera"].__setitem__("matrix_world", [[1e300 * v for v in row] for row in
                                                                        c["camera"]["matrix_world"][:3]] +
                                                        [[0, 0, 0, 1]]), 2, "camera.matrix_world: "),
    "NaN box": (lambda c: c["boxes"][0].__setitem__("max", [1, float("nan"), 1]), 2, "boxes[0].max: "),
    "near 1e-6 far 1e9": (lambda c: c["camera"].update(near=1e-6, far=1e9), 2, "camera.far: "),   # (as Blender's)
    "near 1e-6 far 16": (lambda c: c["camera"].update(near=1e-6, far=16), 0, ""),        # (1:1.6e7, within 1:2^24)
    "a light at the camera": (lambda c: c.__setitem__("light", {"type": "POINT", "position": [
        row[3] for row in c["camera"]["matrix_world"][:3]]}), 0, ""),
    "a scene 1e7 from the origin": (lambda c: _shift_config(c, 1e7), 0, ""),
}


def _shift_config(config, dx):
    for b in config["boxes"]:
        b["min"][0] += dx
        b["max"][0] += dx
    config["camera"]["matrix_world"][0][3] += dx


@pytest.mark.parametrize("name", list(CLI_CASES))
def test_the_audit_catalogue_through_the_cli(name, tmp_path, capsys):
    import json
    from pathlib import Path
    from addon.cli import main
    change, code, message = CLI_CASES[name]
    config = json.loads((Path(__file__).resolve().parents[2] / "examples" / "outdoor_sun.json").read_text())
    change(config)
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "all", str(path)]) == code
    out = capsys.readouterr()
    assert "Traceback" not in out.err and "internal error" not in out.err + out.out
    if code:
        assert out.err.count("\n") == 1 and message in out.err, out.err
    else:
        doc = json.loads(out.out)
        assert all(m["maps"] or "empty_body" in m["diagnostics"] for m in doc["methods"].values())
