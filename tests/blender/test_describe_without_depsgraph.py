"""``describe_view`` and ``describe_scene`` called from a user's script with ``scene.view_layers[0].depsgraph`` of a
scene the window does not show: Blender has made none there (None), and ``describe_view`` handed None to
``Object.calc_matrix_camera``, which crashed Blender (segmentation fault, 4.2.23 and 5.0.1). Run in a child process,
where a crash is an exit status, not the end of the test session."""
import subprocess
import sys
from pathlib import Path

import pytest

DESCRIBE = r"""
import importlib, sys
sys.path.insert(0, sys.argv[1])
import bpy
import conftest
from ui_scenes import build
describe = importlib.import_module(conftest.enable_lixel().__name__ + ".addon.scene.describe")
scene = bpy.data.scenes.new("Other")       # not the window's scene: it has no depsgraph yet
build(scene)
dg = scene.view_layers[0].depsgraph
print("depsgraph", dg, flush=True)
view = describe.describe_view(scene.camera, dg, scene) if sys.argv[2] == "view" else \
    describe.describe_scene(scene, dg)[0]
print("near", round(view.near, 6), "far", view.far, flush=True)
conftest.disable_lixel()
"""


@pytest.mark.parametrize("entry", ["view", "scene"])
def test_describing_a_scene_not_shown_with_its_missing_depsgraph_does_not_crash(entry):
    r = subprocess.run([sys.executable, "-c", DESCRIBE, str(Path(__file__).resolve().parent), entry],
                       capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, (r.returncode, r.stderr[-800:])
    lines = r.stdout.strip().splitlines()
    assert "depsgraph None" in lines and lines[-1] == "near 0.1 far 60.0", r.stdout
