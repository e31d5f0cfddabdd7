"""The headless GPU bootstrap, in a fresh process (a test process usually has a
context already)."""
import os
import subprocess
import sys
from pathlib import Path

SCRIPT = r'''
import importlib.util, sys
import bpy, gpu
conftest = sys.argv[1]
spec = importlib.util.spec_from_file_location("bconf", conftest)
bconf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bconf)
root = bconf.enable_lixel()
ctx = importlib.import_module(root.__name__ + ".addon.gpu.context")
before = {name: sorted(i.name for i in getattr(bpy.data, name)) for name in ("scenes", "objects", "cameras")}
engine = bpy.context.scene.render.engine
print("AVAILABLE_BEFORE", ctx.gpu_available())
ctx.ensure_gpu_context()
print("AVAILABLE_AFTER", ctx.gpu_available())
tex = gpu.types.GPUTexture((4, 4), format="DEPTH_COMPONENT32F")
after = {name: sorted(i.name for i in getattr(bpy.data, name)) for name in ("scenes", "objects", "cameras")}
print("UNTOUCHED", before == after and bpy.context.scene.render.engine == engine)
print("BOOT_ENGINE_GONE", bpy.types.RenderEngine.bl_rna_get_subclass_py("LIXEL_GPU_BOOTSTRAP") is None)
ctx.ensure_gpu_context()  # a second call is a no-op
bconf.disable_lixel()
'''


def test_bootstrap_leaves_the_users_data_alone(tmp_path, lixel):
    script = tmp_path / "boot.py"
    script.write_text(SCRIPT)
    conftest = Path(__file__).with_name("conftest.py")
    proc = subprocess.run([sys.executable, str(script), str(conftest)], capture_output=True, text=True, timeout=300,
                          env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-2000:]
    keys = ("AVAILABLE_BEFORE", "AVAILABLE_AFTER", "UNTOUCHED", "BOOT_ENGINE_GONE")
    out = dict(line.split(" ", 1) for line in proc.stdout.splitlines() if line.startswith(keys))
    assert out.get("AVAILABLE_BEFORE") == "False"
    assert out.get("AVAILABLE_AFTER") == "True"
    assert out.get("UNTOUCHED") == "True"
    assert out.get("BOOT_ENGINE_GONE") == "True"
