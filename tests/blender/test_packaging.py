"""The extension zip (``make extension``) holds only what the extension needs,
its manifest passes Blender's validator and names a website and a maintainer
contact, and the zip installs and registers in a fresh Blender."""
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]
EXTENSION_ENTRIES = {"__init__.py", "blender_manifest.toml", "addon", "gpu_shaders"}


def _cli() -> str:
    # bpy.__file__ is <version>/scripts/modules/bpy/__init__.py inside the wheel
    cli = Path(bpy.__file__).resolve().parents[2] / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    if not cli.is_file():
        pytest.skip("this bpy build has no extension CLI")
    return str(cli)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, _cli(), "build", "--source-dir", str(ROOT), "--output-dir", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (zip_path,) = out.glob("lixel-*.zip")
    return zip_path


def test_zip_holds_only_the_extension(built):
    names = zipfile.ZipFile(built).namelist()
    top = {n.split("/")[0] for n in names}
    assert top == EXTENSION_ENTRIES, top ^ EXTENSION_ENTRIES
    assert not [n for n in names if n.endswith((".blend", ".png", ".pyc")) or "__pycache__" in n]
    assert "addon/gpu/pipeline.py" in names and "gpu_shaders/shade_frag.glsl" in names


def test_manifest_names_a_website_and_a_contact_and_validates(built):
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert manifest["website"].startswith("https://")
    assert "<" in manifest["maintainer"] and "@" in manifest["maintainer"]
    for target in (ROOT, built):
        proc = subprocess.run([sys.executable, _cli(), "validate", str(target)], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stdout + proc.stderr


INSTALL = """
import sys, bpy, addon_utils
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
name = "bl_ext.user_default.lixel"
assert addon_utils.check(name)[1], "not enabled"
assert "LIXEL" in {getattr(e, "bl_idname", "") for e in bpy.types.RenderEngine.__subclasses__()}, "no engine"
assert hasattr(bpy.types.Scene, "lixel"), "no scene properties"
addon_utils.disable(name, default_set=True)
print("INSTALLED")
"""


def test_the_zip_installs_and_registers_in_a_fresh_blender(built, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"), XDG_CACHE_HOME=str(tmp_path / "xdg"))
    proc = subprocess.run([sys.executable, "-c", INSTALL, str(built)], capture_output=True, text=True, timeout=180,
                          env=env, cwd=tmp_path)
    assert proc.returncode == 0 and "INSTALLED" in proc.stdout, proc.stdout[-2000:] + proc.stderr[-2000:]
