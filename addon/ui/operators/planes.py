"""Planes of interest (Chong-Gortler §3) from the selection: selected faces in
Edit Mode, else the largest face of each selected mesh object."""
import bmesh
import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty

from ...guard import guarded_operator
from ...scene.owned import DEBUG_KEY
from .common import LixelSceneOperator, initialise, scene_poll

COPLANAR_ANGLE = 1e-4
"""Faces whose normals differ by less than this (radians) and whose planes are
closer than ``COPLANAR_DISTANCE`` of the object's size are one plane."""
COPLANAR_DISTANCE = 1e-5


def face_plane(matrix, centre, normal) -> tuple[np.ndarray, np.ndarray]:
    """A local face (centre, normal) as a world (point, unit normal)."""
    m = np.asarray(matrix, dtype=np.float64)
    point = m[:3, :3] @ np.asarray(centre, dtype=np.float64) + m[:3, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        try:
            n = np.linalg.inv(m[:3, :3]).T @ np.asarray(normal, dtype=np.float64)  # normals: the inverse transpose
        except np.linalg.LinAlgError:  # a zero-scale object: no plane (refused by the caller)
            return point, np.full(3, np.nan)
        return point, n / np.linalg.norm(n)


def merge_coplanar(planes, scale: float) -> list:
    out = []
    for p, n, src in planes:
        if any(abs(float(np.dot(n, n2))) > np.cos(COPLANAR_ANGLE) and abs(float(np.dot(p - p2, n2))) < COPLANAR_DISTANCE * scale
               for p2, n2, _ in out):
            continue
        out.append((p, n, src))
    return out


def selected_face_planes(context) -> list:
    planes = []
    for ob in context.objects_in_mode_unique_data if context.mode == "EDIT_MESH" else []:
        bm = bmesh.from_edit_mesh(ob.data)
        m = np.array(ob.matrix_world)
        for f in bm.faces:
            if f.select and f.normal.length > 0:
                p, n = face_plane(m, f.calc_center_median(), f.normal)
                planes.append((p, n, f"{ob.name} face {f.index}"))
    return planes


def largest_face_planes(context) -> list:
    planes = []
    for ob in context.selected_objects:
        if ob.type != "MESH" or ob.get(DEBUG_KEY) is not None or len(ob.data.polygons) == 0:
            continue
        mesh = ob.data
        areas = np.zeros(len(mesh.polygons))
        mesh.polygons.foreach_get("area", areas)
        f = mesh.polygons[int(np.argmax(areas))]  # a NaN area wins argmax, and its plane is refused
        p, n = face_plane(np.array(ob.matrix_world), f.center, f.normal)
        planes.append((p, n, f"{ob.name} (largest face)"))
    return planes


class LIXEL_OT_planes_from_selection(LixelSceneOperator, bpy.types.Operator):
    """Set the planes of interest (for the plane-optimal method) from the selected faces in Edit Mode, or from the largest face of each selected mesh object"""

    bl_idname = "lixel.planes_from_selection"
    bl_label = "Planes From Selection"
    bl_options = {"REGISTER", "UNDO"}

    append: BoolProperty(name="Append", default=False, description="Add to the existing planes instead of replacing them")

    @guarded_operator
    def execute(self, context):
        initialise(context)
        planes = selected_face_planes(context) if context.mode == "EDIT_MESH" else largest_face_planes(context)
        bad = [src for p, n, src in planes if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n)))]
        if bad:
            self.report({"ERROR"}, f"Lixel: {bad[0]} has no plane (non-finite vertex coordinates, or no area): "
                                   f"fix its vertices or select another face")
            return {"CANCELLED"}
        if not planes:
            what = "no face selected" if context.mode == "EDIT_MESH" else "no mesh selected"
            self.report({"ERROR"}, f"Lixel: {what}: select the faces (Edit Mode) or mesh objects "
                                   f"that should get their own shadow map")
            return {"CANCELLED"}
        scale = max(max(float(np.abs(p).max()) for p, _, _ in planes), 1.0)
        planes = merge_coplanar(planes, scale)
        props = context.scene.lixel
        if not self.append:
            props.planes.clear()
        for p, n, src in planes:
            item = props.planes.add()
            item.point, item.normal, item.source = tuple(p), tuple(n), src
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
        return scene_poll(cls, context) and len(context.scene.lixel.planes) > 0

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
