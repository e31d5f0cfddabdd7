"""The extension installs, registers and unregisters like any Blender extension."""
import bpy


def test_enables_as_extension(lixel):
    assert lixel.__name__ == "bl_ext.lixel_dev.lixel"
    assert hasattr(lixel, "register") and hasattr(lixel, "unregister")


def test_math_core_imports_without_bpy_dependency(lixel):
    import importlib
    warp = importlib.import_module(lixel.__name__ + ".addon.warp.types")
    assert warp.View is not None
