"""Lixel's Blender user interface: scene settings, preferences, the sidebar
panel, viewport overlays and geometry-node tooling (imports bpy in its modules,
not here)."""
