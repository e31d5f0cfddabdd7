"""The shadow maps' GPU memory is estimated before anything is allocated (``addon.gpu.targets.check_map_memory``):
a cascade of 8 splits at 16384² per map (8 GiB of depth, 40 GiB with MDSM keys) was attempted and failed deep in the
GPU module or took the machine's memory; now F12, scripts and the panel's renders refuse it, naming the settings that
size the maps and what to do. The CLI only computes matrices and allocates nothing."""
import importlib
import json
import math
from pathlib import Path

import bpy
import pytest
from mathutils import Vector

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def targets(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.gpu.targets")


class _Map:
    def __init__(self, size, role="uniform"):
        self.size, self.role = size, role


class _Setup:
    def __init__(self, *maps):
        self.maps = list(maps)


def test_what_fits_and_what_is_refused(targets):
    cascade_4096 = _Setup(*[_Map((4096, 4096), f"split{i}:uniform") for i in range(8)])
    assert targets.map_bytes([m.size for m in cascade_4096.maps], mdsm=True) == 8 * 4096 ** 2 * 20   # 2.5 GiB
    targets.check_map_memory(cascade_4096, mdsm=True)
    with pytest.raises(targets.WarpError) as cascade:
        targets.check_map_memory(_Setup(*[_Map((16384, 16384), f"split{i}:lispsm") for i in range(8)]))
    assert str(cascade.value) == ("8 shadow maps of 16384x16384 texels would take 8.0 GiB of GPU memory, more than "
                                  "Lixel's limit of 4 GiB: lower the Map Size or use fewer Splits or a Shared Texel "
                                  "Budget (Lixel panel > Method; in a script, --size sets the Map Size)")
    with pytest.raises(targets.WarpError) as one:
        targets.check_map_memory(_Setup(_Map((16384, 16384))), mdsm=True)
    assert str(one.value) == ("1 shadow map of 16384x16384 texels with their MDSM keys would take 5.0 GiB of GPU "
                              "memory, more than Lixel's limit of 4 GiB: lower the Map Size or set MDSM Depths to 1 "
                              "(Lixel panel > Method; in a script, --size sets the Map Size)")


def _add(scene, name, data):
    ob = bpy.data.objects.new(name, data)
    scene.collection.objects.link(ob)
    return ob


def test_f12_refuses_maps_over_the_limit_before_allocating_them(engine, fresh_scene, monkeypatch):
    """F12 of a cascade of 8 splits at 16384² per map: the error names the maps, their memory, the settings and
    what to do; no texture of that size is asked of the GPU module (here one would raise MemoryError, as a real
    device does or worse)."""
    import gpu
    scene = fresh_scene
    scene.render.engine = "LIXEL"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 48, 100
    ground = bpy.data.meshes.new("Ground")
    ground.from_pydata([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [], [(0, 1, 2, 3)])
    _add(scene, "Ground", ground)
    cam = _add(scene, "Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0, -12, 3)
    cam.rotation_euler = (Vector((0, 10, 0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.clip_end = 60.0
    scene.camera = cam
    sun = _add(scene, "Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(30), 0, math.radians(20))
    lx = scene.lixel
    lx.method, lx.cascade_splits, lx.cascade_budget = "cascade", 8, "per_map"
    lx.shadow_map_size = (16384, 16384)
    real = gpu.types.GPUTexture

    def texture(size, *args, **kwargs):
        if size[0] * size[1] >= 16384 ** 2:
            raise MemoryError(f"a {size[0]}x{size[1]} texture asked for")
        return real(size, *args, **kwargs)

    monkeypatch.setattr(gpu.types, "GPUTexture", texture)
    with pytest.raises(RuntimeError) as refused:
        bpy.ops.render.render(scene=scene.name)
    said = str(refused.value)
    assert "shadow maps of 16384x16384 texels would take" in said and "more than Lixel's limit of 4 GiB: lower the " \
           "Map Size or use fewer Splits or a Shared Texel Budget (Lixel panel > Method; in a script, --size sets " \
           "the Map Size)" in said, said
    lx.shadow_map_size = (1024, 1024)       # what the message says to do
    assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}


def test_the_cli_computes_such_a_cascade_without_allocating(tmp_path, capsys, lixel):
    """The CLI only computes matrices: 8 splits at 16384² is a config it answers."""
    main = importlib.import_module(f"{lixel.__name__}.addon.cli").main
    config = json.loads((ROOT / "examples" / "outdoor_sun.json").read_text())
    config["shadow_map_size"] = 16384
    config["options"] = {"cascade_splits": 8}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "cascade", str(path)]) == 0, capsys.readouterr().err
    maps = json.loads(capsys.readouterr().out)["maps"]
    assert len(maps) == 8 and all(m["size"] == [16384, 16384] for m in maps)


def test_a_script_refusing_such_maps_names_its_own_size_option(lixel, tmp_path):
    """A script's ``--size`` sets the maps' size, not the panel's Map Size (the file keeps its own): the refusal
    told a script's user to lower the Map Size in the Lixel panel, which the script then overrode again. It names
    ``--size`` too; one line, exit 1, no picture written."""
    from test_scripts import run
    from ui_scenes import active_scene
    path = tmp_path / "cascade.blend"
    with active_scene("lixel_memory_script") as scene:
        lx = scene.lixel
        lx.method, lx.cascade_splits, lx.cascade_budget = "cascade", 8, "per_map"
        lx.shadow_map_size = (1024, 1024)
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    out = tmp_path / "x.png"
    r = run("module", "render_method.py", path, "--size", "16384", "--output", str(out), "--resolution", "64x48")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    said = [line for line in r.stderr.splitlines() if line.startswith("lixel: error:")]
    assert len(said) == 1 and "shadow maps of 16384x16384 texels would take 8.0 GiB" in said[0], r.stderr
    assert "--size" in said[0], said[0]
    assert not out.exists()
