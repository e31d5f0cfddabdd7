"""Lixel's operators (``LIXEL_OT_*``): refresh, overlays, bake, export, compare,
overlay snapshots, planes of interest, geometry-node tooling."""
import bpy

from . import bake, export, planes, setup, snapshot

classes = setup.classes + bake.classes + export.classes + snapshot.classes + planes.classes


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(classes)
