"""Lixel's operators (``LIXEL_OT_*``): refresh, overlays, bake, export, compare,
planes of interest, geometry-node tooling."""
import bpy

from . import bake, export, planes, setup

classes = setup.classes + bake.classes + export.classes + planes.classes


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
