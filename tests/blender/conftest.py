"""Blender-module test harness.

The extension is installed from this working tree as ``bl_ext.lixel_dev.lixel``
through a user repository whose ``lixel`` entry is a symlink to the repo root,
exactly as Blender loads an installed extension. Everything registered is
unregistered at the end of the session (Blender 4.2/4.5 crash or hang at exit
otherwise; see shared notes §8.5).
"""
import atexit
import os
import tempfile
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]
REPO_MODULE = "lixel_dev"
ADDON_MODULE = f"bl_ext.{REPO_MODULE}.lixel"


def _ensure_repo() -> None:
    repos = bpy.context.preferences.extensions.repos
    if any(r.module == REPO_MODULE for r in repos):
        return
    directory = Path(tempfile.mkdtemp(prefix="lixel-ext-repo-"))
    (directory / "lixel").symlink_to(ROOT, target_is_directory=True)
    repos.new(name="Lixel dev", module=REPO_MODULE, custom_directory=str(directory), source="USER")


def enable_lixel():
    """Enable the extension (idempotent) and return its root module."""
    import addon_utils
    import importlib
    _ensure_repo()
    addon_utils.enable(ADDON_MODULE, default_set=True, handle_error=_raise)
    return importlib.import_module(ADDON_MODULE)


def disable_lixel() -> None:
    import addon_utils
    addon_utils.disable(ADDON_MODULE, default_set=True, handle_error=_raise)


def _raise(exc):
    raise exc


@atexit.register
def _unregister_everything() -> None:
    # Last line of defence for the 4.2/4.5 exit crash: nothing of ours may stay registered.
    try:
        import addon_utils
        if ADDON_MODULE in {m.__name__ for m in addon_utils.modules()} and addon_utils.check(ADDON_MODULE)[1]:
            disable_lixel()
    except Exception:
        pass


@pytest.fixture(scope="session")
def lixel():
    """The enabled Lixel extension's root module (registered for the whole session)."""
    mod = enable_lixel()
    yield mod
    disable_lixel()


@pytest.fixture(scope="module")
def engine(lixel):
    """The enabled extension's render engine module (``addon.render.engine``)."""
    import importlib
    return importlib.import_module(lixel.__name__ + ".addon.render.engine")


@pytest.fixture
def load_pixels(lixel):
    """The enabled extension's ``addon.ui.renders.load_pixels``: an image file's pixels, float32 (H, W, channels)."""
    import importlib
    return importlib.import_module(lixel.__name__ + ".addon.ui.renders").load_pixels


def remove_objects_and_orphans(scene) -> None:
    """Remove the scene's objects and the data they leave without users."""
    obs = list(scene.objects)
    datas = [ob.data for ob in obs if ob.data is not None]
    bpy.data.batch_remove(obs)
    orphans = []
    for d in datas:
        try:
            if d.users == 0:
                orphans.append(d)
        except ReferenceError:   # already freed with its object
            pass
    bpy.data.batch_remove(orphans)


@pytest.fixture
def fresh_scene():
    """An empty scene made active for the test; it, its objects and their
    orphaned data are removed afterwards."""
    old = bpy.context.window.scene if bpy.context.window else bpy.context.scene
    scene = bpy.data.scenes.new("lixel_test")
    if bpy.context.window:
        bpy.context.window.scene = scene
    yield scene
    if bpy.context.window:
        bpy.context.window.scene = old
    remove_objects_and_orphans(scene)
    bpy.data.scenes.remove(scene)
