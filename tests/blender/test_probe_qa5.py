import bpy, numpy as np, pytest
from test_render_engine import build, _add_hold, _render, _inside, add, cube_mesh, scene, _instancer, _remove_instancer, _instanced_pixels  # noqa

def _cycles(scene, tmp_path, load_pixels):
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 32, False, "CPU"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    scene.render.engine = "LIXEL"
    return load_pixels(scene.render.filepath)

@pytest.mark.parametrize("kind", ["collection", "nodes"])
@pytest.mark.parametrize("who", ["instancer", "instanced"])
@pytest.mark.parametrize("flag", ["visible_shadow", "visible_camera"])
def test_probe(kind, who, flag, engine, scene, tmp_path, load_pixels):
    build(scene)
    instanced = bpy.data.objects.new("Hold", cube_mesh("Hold", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    plain_l = _render(engine, scene, read={"world_position"})
    inst = _instanced_pixels(plain_l["result"].world_position)
    plain = _cycles(scene, tmp_path, load_pixels)
    host.hide_render = True
    hidden = _cycles(scene, tmp_path, load_pixels)
    hidden_l = _render(engine, scene)["result"].combined
    host.hide_render = False
    setattr(host if who == "instancer" else instanced, flag, False)
    got = _cycles(scene, tmp_path, load_pixels)
    got_l = _render(engine, scene)["result"].combined
    sel = ~inst if flag == "visible_shadow" else inst
    print(f"\nPROBE {kind} {who} {flag}: cycles |got-plain| {np.abs(got-plain)[sel].mean():.4f} |got-hidden| {np.abs(got-hidden)[sel].mean():.4f}"
          f"  lixel |got-plain| {np.abs(got_l-plain_l['result'].combined)[sel].mean():.4f} |got-hidden| {np.abs(got_l-hidden_l)[sel].mean():.4f}")
    _remove_instancer(host, instanced)
