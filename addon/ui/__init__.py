"""Lixel's Blender user interface: scene settings, preferences, the sidebar
panel, operators, viewport overlays and geometry-node tooling (imports bpy in
its modules, not here)."""

ROOT_PACKAGE = __package__.rsplit(".addon.ui", 1)[0] if __package__.endswith(".addon.ui") else __package__
"""The extension's root package (``bl_ext.<repo>.lixel``): the preferences' ``bl_idname``."""


def addon_preferences():
    """Lixel's registered add-on preferences, or None (not registered, e.g. a
    script that imported the checkout without enabling it)."""
    import bpy
    addon = bpy.context.preferences.addons.get(ROOT_PACKAGE)
    return addon.preferences if addon is not None else None
