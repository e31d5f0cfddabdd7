"""Planes of interest (Chong-Gortler §3) from the selection: the coplanar selected faces in
Edit Mode, else the largest flat face group of each selected mesh object (``addon.scene.planes``)."""
import bpy
from bpy.props import BoolProperty, IntProperty

from ...guard import guarded_operator
from ...scene.owned import DEBUG_KEY
from ...scene.planes import NoPlane, planes_from_objects, planes_from_selected_faces
from ...warp.plane_map import enclosing_polygon
from ..properties import PLANE_CORNERS
from .common import LixelSceneOperator, editable_scene_poll, initialise, not_meshes_note, selected_shapes_not_meshes


def selection_planes(context) -> list:
    """The planes of interest of the selection (NoPlane naming an object without one)."""
    if context.mode == "EDIT_MESH":
        return planes_from_selected_faces(context.objects_in_mode_unique_data)
    meshes = [ob for ob in context.selected_objects if ob.type == "MESH" and ob.get(DEBUG_KEY) is None]
    return planes_from_objects(meshes, context.evaluated_depsgraph_get()) if meshes else []


class LIXEL_OT_planes_from_selection(LixelSceneOperator, bpy.types.Operator):
    """Set the planes of interest (for the plane-optimal method) from the selected faces in Edit Mode, or from the largest flat surface of each selected mesh object"""

    bl_idname = "lixel.planes_from_selection"
    bl_label = "Planes From Selection"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    append: BoolProperty(name="Append", default=False, description="Add to the existing planes instead of replacing them")

    @guarded_operator
    def execute(self, context):
        initialise(context)
        try:
            planes = selection_planes(context)
        except NoPlane as exc:
            self.report({"ERROR"}, f"Lixel: {exc}")
            return {"CANCELLED"}
        shapes = [] if context.mode == "EDIT_MESH" else selected_shapes_not_meshes(context)
        if not planes:
            what = "no face selected" if context.mode == "EDIT_MESH" else "no mesh selected"
            what += f" ({not_meshes_note(shapes)})" if shapes else ""
            self.report({"ERROR"}, f"Lixel: {what}: select the faces (Edit Mode) or mesh objects "
                                   f"that should get their own shadow map")
            return {"CANCELLED"}
        if shapes:
            self.report({"WARNING"}, f"Lixel: planes of interest come from meshes: {not_meshes_note(shapes)}")
        props = context.scene.lixel
        if not self.append:
            props.planes.clear()
        for plane in planes:
            item = props.planes.add()   # a point on the faces: the middle of their extent's corners
            item.point, item.normal, item.source = tuple(plane.extent.mean(axis=0)), tuple(plane.normal), plane.name
            item.set_extent(enclosing_polygon(plane.extent, plane.normal, PLANE_CORNERS))
        props.active_plane = len(props.planes) - 1
        msg = f"Lixel: {len(props.planes)} plane(s) of interest"
        if props.method != "plane_optimal":
            msg += " (used by the Plane optimal method)"
        self.report({"INFO"}, msg)
        return {"FINISHED"}


class LIXEL_OT_plane_remove(bpy.types.Operator):
    """Remove a plane of interest"""

    bl_idname = "lixel.plane_remove"
    bl_label = "Remove Plane"
    bl_options = {"REGISTER", "UNDO"}

    index: IntProperty(name="Index", default=-1, description="The plane to remove (-1: all)")

    @classmethod
    def poll(cls, context):
        return editable_scene_poll(cls, context) and len(context.scene.lixel.planes) > 0

    @guarded_operator
    def execute(self, context):
        props = context.scene.lixel
        if self.index < 0:
            props.planes.clear()
        elif self.index < len(props.planes):
            props.planes.remove(self.index)
        else:
            self.report({"ERROR"}, f"Lixel: there is no plane {self.index} (there are {len(props.planes)})")
            return {"CANCELLED"}
        props.active_plane = max(0, min(props.active_plane, len(props.planes) - 1))
        return {"FINISHED"}


classes = (LIXEL_OT_planes_from_selection, LIXEL_OT_plane_remove)
