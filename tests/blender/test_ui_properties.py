"""``scene.lixel`` mirrors LixelSettings / WarpOptions / ShadowSettings field
for field: a round trip through the properties keeps every value, the
preferences give new scenes their defaults, and a user's edit is never
overwritten by them."""
import dataclasses
import importlib
import math

import bpy
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    m.settings = importlib.import_module(f"{lixel.__name__}.addon.settings")
    m.types = importlib.import_module(f"{lixel.__name__}.addon.warp.types")
    m.properties = importlib.import_module(f"{lixel.__name__}.addon.ui.properties")
    m.preferences = importlib.import_module(f"{lixel.__name__}.addon.ui.preferences")
    return m


def custom_settings(mods):
    """Every field away from its default."""
    warp = mods.types.WarpOptions(
        shadow_map_size=(1024, 512), focus="view", lambda_guard="off", texel_snapping=True, delta_z="visible", visible_depth_range=(0.5, 40.0),
        middle_vector=True, linear_z=False, lam=0.25, max_frustum_angle=math.radians(95.0),
        planes=(((0.0, 0.0, 0.5), (0.0, 0.0, 1.0)), ((1.0, 0.0, 0.0), (1.0, 0.0, 0.0))), plane_budget=0.5,
        plane_twist="off", cascade_splits=3, cascade_warp="lispsm", cascade_lambda=0.75, cascade_adaptive=False,
        cascade_stable=True, cascade_budget="shared", cascade_blend=0.2)
    shadow = mods.settings.ShadowSettings(
        bias_mode="SLOPE", constant_bias=0.002, slope_bias=2.5, normal_offset=2.0, back_faces=True, pcf_kernel=5,
        revectorize=True,
        mdsm_depths=3, mdsm_selection="SORT", mdsm_neighbourhood=5, eye_blur=2.0)
    return mods.settings.LixelSettings(method="gmnpr", warp=warp, shadow=shadow)


def test_every_field_is_mirrored(mods):
    s = custom_settings(mods)
    defaults = mods.settings.LixelSettings()
    for group in ("warp", "shadow"):
        for f in dataclasses.fields(getattr(s, group)):
            assert getattr(getattr(s, group), f.name) != getattr(getattr(defaults, group), f.name), \
                f"{group}.{f.name} is new: mirror it in addon/ui/properties.py and set it in custom_settings()"


def test_round_trip_keeps_every_value(lixel, mods):
    with active_scene("lixel_props") as scene:
        s = custom_settings(mods)
        scene.lixel.from_settings(s)
        back = scene.lixel.to_settings()
        assert back.method == s.method
        for group in ("warp", "shadow"):  # Blender stores floats as float32
            for f in dataclasses.fields(getattr(s, group)):
                a, b = getattr(getattr(back, group), f.name), getattr(getattr(s, group), f.name)
                if isinstance(b, float):
                    assert a == pytest.approx(b, rel=1e-6), f.name
                elif f.name == "planes":
                    assert [(tuple(map(float, p)), tuple(map(float, n))) for p, n in a] == list(b)
                elif f.name == "visible_depth_range":
                    assert a == pytest.approx(b), f.name
                else:
                    assert a == b, f.name


def test_preferences_apply_to_new_scenes_only(lixel, mods):
    prefs = mods.preferences.preferences()
    assert prefs is not None and type(prefs).bl_idname == mods.preferences.ROOT_PACKAGE == lixel.__name__
    old = (prefs.method, prefs.map_size, prefs.pcf_kernel)
    prefs.method, prefs.map_size, prefs.pcf_kernel = "uniform", 512, 2
    try:
        with active_scene("lixel_prefs_new") as scene:
            assert mods.properties.ensure_defaults(scene)
            got = scene.lixel.to_settings()
            assert (got.method, got.warp.shadow_map_size, got.shadow.pcf_kernel) == ("uniform", (512, 512), 2)
            assert not mods.properties.ensure_defaults(scene)  # only once
        with active_scene("lixel_prefs_edited") as scene:
            # never set up: it renders with the preferences, and nothing is written into it
            assert not scene.lixel.initialised and scene.lixel.method == "lispsm"
            got = scene.lixel.to_settings()
            assert (got.method, got.warp.shadow_map_size, got.shadow.pcf_kernel) == ("uniform", (512, 512), 2)
            scene.lixel.method = "psm"  # the user's first choice, before any refresh: the rest stays as rendered
            assert not mods.properties.ensure_defaults(scene)
            assert scene.lixel.method == "psm" and scene.lixel.pcf_kernel == 2
            assert tuple(scene.lixel.shadow_map_size) == (512, 512)
    finally:
        prefs.method, prefs.map_size, prefs.pcf_kernel = old


def test_new_scenes_take_the_preferences_live_update_and_body_opacity(lixel, mods):
    """Preferences > New Scenes shows Live Update and Body Opacity: they were never applied (Live Update off there
    left every new scene updating live, a Body Opacity of 0.6 drew B at 0.15), nor by Reset to Preferences. A new
    scene takes them with the rest; a user's first edit of one is kept, as of any setting."""
    prefs = mods.preferences.preferences()
    old = (prefs.live_update, prefs.body_alpha)
    prefs.live_update, prefs.body_alpha = False, 0.6
    try:
        with active_scene("lixel_prefs_view") as scene:
            assert mods.properties.ensure_defaults(scene)
            assert not scene.lixel.live_update and scene.lixel.body_alpha == pytest.approx(0.6)
            scene.lixel.live_update, scene.lixel.body_alpha = True, 0.3
            assert bpy.ops.lixel.reset_settings() == {"FINISHED"}
            assert not scene.lixel.live_update and scene.lixel.body_alpha == pytest.approx(0.6)
        with active_scene("lixel_prefs_view_edited") as scene:
            scene.lixel.body_alpha = 0.3          # the first edit of a scene never set up
            assert scene.lixel.initialised and not scene.lixel.live_update
            assert scene.lixel.body_alpha == pytest.approx(0.3)
    finally:
        prefs.live_update, prefs.body_alpha = old


def test_light_poll_accepts_only_lights(lixel):
    with active_scene("lixel_props_light") as scene:
        poll = type(scene.lixel).__annotations__["light"].keywords["poll"]
        assert poll(scene.lixel, scene.objects["lixel_props_light light"])
        assert not poll(scene.lixel, scene.camera)


LOAD_SUBPROCESS = r'''
import importlib, importlib.util, json, sys
import bpy
conftest, blend = sys.argv[1:3]
spec = importlib.util.spec_from_file_location("bconf", conftest)
bconf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bconf)
root = bconf.enable_lixel()
prefs = importlib.import_module(root.__name__ + ".addon.ui.preferences").preferences()
prefs.method, prefs.map_size = "uniform", 512
bpy.ops.wm.open_mainfile(filepath=blend)
engine = importlib.import_module(root.__name__ + ".addon.render.engine")
out = {"scenes": {}}
for sc in bpy.data.scenes:
    s = engine.scene_settings(sc)
    out["scenes"][sc.name] = {"initialised": sc.lixel.initialised, "method": sc.lixel.method,
                              "renders_with": [s.method, list(s.warp.shadow_map_size)]}
print("LIXEL_LOADED " + json.dumps(out))
bconf.disable_lixel()
'''


def test_opening_a_file_writes_nothing_into_its_scenes(lixel, tmp_path):
    """Opening a .blend leaves every scene as saved (no Lixel settings written on
    load); a scene never set up renders with the preference defaults."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path
    blend = tmp_path / "two_scenes.blend"
    first = bpy.data.scenes.new("lixel_never_set_up_a")
    second = bpy.data.scenes.new("lixel_never_set_up_b")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    finally:
        bpy.data.scenes.remove(first)
        bpy.data.scenes.remove(second)
    script = tmp_path / "load.py"
    script.write_text(LOAD_SUBPROCESS)
    conftest = Path(__file__).with_name("conftest.py")
    proc = subprocess.run([sys.executable, str(script), str(conftest), str(blend)], capture_output=True, text=True,
                          timeout=300, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-2000:]
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("LIXEL_LOADED ")]
    got = json.loads(line[0].split(" ", 1)[1])
    # (bpy.data.is_dirty cannot tell: it is True after any open_mainfile in background mode)
    for name in ("lixel_never_set_up_a", "lixel_never_set_up_b"):
        assert got["scenes"][name] == {"initialised": False, "method": "lispsm", "renders_with": ["uniform", [512, 512]]}


@pytest.mark.parametrize("method, refused", [("gmnpr", True), ("glpr", True), ("cascade", True), ("lispsm", False)])
def test_a_forced_lambda_of_zero_is_refused_by_name_where_it_is_used(lixel, method, refused):
    """The λ field's minimum is 0: with Override λ on, Refresh and F12 said "the forced λ must be positive (got 0.0);
    leave it unset for Eq. 8", naming no scene and no field of the panel. It names them and what to do, wherever
    the λ reaches (GMNPR, GLPR, the cascade's GMNPR splits); where it does not (LiSPSM), the scene computes."""
    with active_scene("lixel_lambda") as scene:
        scene.lixel.method, scene.lixel.use_lambda, scene.lixel.lam = method, True, 0.0
        if not refused:
            assert bpy.ops.lixel.refresh() == {"FINISHED"}
            return
        with pytest.raises(RuntimeError, match=r"Lixel: Scene 'lixel_lambda' forces λ = 0: a forced λ must be "
                                               r"positive; raise it or turn Override λ off \(Lixel panel > Method, "
                                               r"with GMNPR or GLPR\)"):
            bpy.ops.lixel.refresh()
        scene.lixel.lam = 0.25
        assert bpy.ops.lixel.refresh() == {"FINISHED"}


def test_an_eye_blur_beyond_what_renders_in_time_is_refused_by_name(lixel):
    """Eye Blur has no hard maximum (soft 8 px): a typed 1000 made every seen pixel read its 2001² neighbours, hours
    for one 1080p frame and a frozen Blender under the viewport's shadowed overlay (150 px took 0.47 s at 64x36,
    2e8 reads). It is refused by name, as typed, before anything renders; 32 px still renders."""
    with active_scene("lixel_blur") as scene:
        scene.lixel.initialised = True
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 18, 100
        scene.lixel.eye_blur = 1000.0
        for op in (bpy.ops.lixel.refresh, bpy.ops.render.render):
            with pytest.raises(RuntimeError, match=r"Scene 'lixel_blur' has an Eye Blur of 1000 px, beyond the 32 px "
                                                   r"Lixel blurs .*: lower it \(Lixel panel > Shadows > Eye Blur\)"):
                op()
        assert scene.lixel.eye_blur == 1000.0
        scene.lixel.eye_blur = 32.0
        assert bpy.ops.render.render() == {"FINISHED"}


@pytest.mark.parametrize("name, label, panel", [
    ("constant_bias", "Constant Bias", "Shadows"), ("slope_bias", "Slope Bias", "Shadows"),
    ("normal_offset", "Normal Offset", "Shadows"), ("max_frustum_angle", "Max Frustum Angle", "Method"),
    ("plane_budget", "Plane Budget", "Method"), ("cascade_lambda", "Split λ", "Method"),
    ("cascade_blend", "Blend Band", "Method")])
def test_a_nan_setting_from_a_script_is_refused_by_name(lixel, mods, name, label, panel):
    """Blender's min and max let a NaN set from Python through (``scene.lixel.normal_offset = a / b``). The biases
    were taken as they were: F12 rendered a NaN Constant Bias with no shadows and a NaN Normal Offset (Normal Offset
    bias) black, without a word; a NaN Max Frustum Angle gave every point light cube faces; the cascade's and the
    planes' NaNs were refused as "plane_budget must be in (0, 1] (got nan)", naming no scene and no field. Each is
    refused by name, in the panel's words, before anything renders."""
    with active_scene("lixel_nan") as scene:
        scene.lixel.initialised = True
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 18, 100
        scene.lixel.bias_mode = "NORMAL_OFFSET" if name == "normal_offset" else "CONSTANT_SLOPE"
        setattr(scene.lixel, name, float("nan"))
        for op in (bpy.ops.lixel.refresh, bpy.ops.render.render):
            with pytest.raises(RuntimeError, match=rf"Lixel: Scene 'lixel_nan' has a {label} of NaN \(set from a "
                                                   rf"script\?\): give it a number \(Lixel panel > {panel} > "
                                                   rf"{label}\), or Reset Settings"):
                op()
        assert bpy.ops.lixel.reset_settings() == {"FINISHED"} and bpy.ops.render.render() == {"FINISHED"}
    if panel == "Shadows":  # scripts that build the plain settings themselves
        with pytest.raises(mods.types.WarpError, match="biases must be >= 0"):
            mods.settings.ShadowSettings(**{name: float("nan")})


@pytest.mark.parametrize("light", ["SUN", "SPOT"])
@pytest.mark.parametrize("field, value", [("energy", float("nan")), ("color", (1.0, float("nan"), 1.0))])
def test_a_light_a_script_gave_a_nan_strength_or_colour_is_named(lixel, light, field, value):
    """``light.data.energy = a / b`` with b = 0 in a script: Blender's field takes the NaN, and F12 rendered the frame
    black (every pixel 0) without a word, the panel's Refresh as if nothing were wrong. The light is named with what
    to do."""
    with active_scene("lixel_nan_light", light=light) as scene:
        scene.lixel.initialised = True
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 18, 100
        setattr(scene.objects["lixel_nan_light light"].data, field, value)
        for op in (bpy.ops.lixel.refresh, bpy.ops.render.render):
            with pytest.raises(RuntimeError, match=r"Lixel: Light 'lixel_nan_light light' has a strength or colour "
                                                   r"of NaN or infinity \(set from a script\?\), which lit nothing "
                                                   r"and rendered black: give it a number \(Light properties > "
                                                   r"Power/Strength, Color, Exposure\)"):
                op()


def test_the_panel_and_the_cli_take_one_max_frustum_angle_range(lixel, mods):
    """The panel's Max Frustum Angle field is bounded by the range the CLI refuses outside
    (``cli.config.FRUSTUM_ANGLE_DEGREES``); the CLI took (0°, 180°) where the panel took 10°-170°."""
    prop = bpy.types.Scene.bl_rna.properties["lixel"].fixed_type.properties["max_frustum_angle"]
    low, high = importlib.import_module(f"{lixel.__name__}.addon.cli.config").FRUSTUM_ANGLE_DEGREES
    assert (prop.hard_min, prop.hard_max) == pytest.approx((math.radians(low), math.radians(high)), rel=1e-6)
