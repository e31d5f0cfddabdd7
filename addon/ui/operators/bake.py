"""Bake the debug geometry (B, the frusta, P's vectors) to mesh objects in the
"Lixel Debug" collection, and the geometry-node tooling (texel grid, frustum
from matrix)."""
import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty

from ...guard import guarded_operator
from ...scene.owned import DEBUG_KEY, is_lixel_made
from ...warp.geometry import finite_clip_volume_corners
from ...warp.polyhedron import hexahedron_faces
from .. import nodes
from .common import LixelSceneOperator, not_meshes_note, selected_shapes_not_meshes

BAKED = "baked"


class MatrixOperator(LixelSceneOperator):
    """An operator that writes the light matrices to the scene's carrier."""

    def say(self, said: list) -> None:
        """Each of ``said`` (what building the node groups left the user: ``nodes._keep_edited``) as a warning."""
        for message in said:
            self.report({"WARNING"}, message)

    def name_followers_of_missing_maps(self, carrier, st) -> None:
        """Reattach the scene's frusta and texel grids that follow no carrier (``nodes.reattach_orphans``: the
        carrier object was deleted), saying so, and a warning naming each object that follows a map ``carrier``
        (holding ``st``'s maps) no longer holds: a frustum showed a 2-unit cube at the origin, a texel grid the
        colours of no map's texels, and nothing said why. Likewise each object following light matrices Sync does
        not write (``nodes.followers_of_other_carriers``: another scene's, or a carrier the user renamed): Sync
        said the matrices were synced while such a grid stayed as it was."""
        if again := nodes.reattach_orphans(bpy.context.scene, carrier):
            self.report({"INFO"}, f"Lixel: {nodes.listed([repr(n) for n in again])} followed no light matrices (the "
                                  f"'{nodes.CARRIER_NAME}' object they followed was deleted): they follow "
                                  f"'{carrier.name}' again")
        if others := nodes.followers_of_other_carriers(bpy.context.scene.objects, carrier, bpy.context.scene):
            one = len(others) == 1
            named = nodes.listed([f"{n!r} (follows {followed(*c)})" for n, c in others.items()])
            self.report({"WARNING"}, f"Lixel: {named} "
                                     f"show{'s' if one else ''} light matrices that are not this scene's "
                                     f"'{carrier.name}', so {'it does' if one else 'they do'} not follow the setup: "
                                     f"select {'it' if one else 'them'} and Add Texel Grid (a frustum: Add Frustum "
                                     f"From Matrix) to follow it (an object in several scenes follows one)")
        count = len(st.setup.maps)
        if stale := nodes.followers_of_missing_maps(carrier, count):
            one = len(stale) == 1
            maps = "map 0 only" if count == 1 else f"maps 0 to {count - 1}"
            self.report({"WARNING"}, f"Lixel: {nodes.listed([f'{name!r} (map {i})' for name, i in stale])} follow"
                                     f"{'s' if one else ''} a map the {st.method_used} setup does not have ({maps}): "
                                     f"what {'it shows' if one else 'they show'} belongs to no map; add "
                                     f"{'it' if one else 'them'} again for one of its maps, or delete "
                                     f"{'it' if one else 'them'}")


def followed(carrier: str, scene: str) -> str:
    """A carrier ``nodes.followers_of_other_carriers`` found, in words."""
    return f"'{carrier}'" + (f" of scene '{scene}'" if scene else "")


def mesh_from_polygons(name, polygons, scene):
    """``scene``'s Lixel mesh ``name`` (new or emptied) from convex polygons, vertices shared
    where polygons meet."""
    mesh = nodes.lixel_mesh(name, scene)
    mesh.clear_geometry()
    verts, index, faces = [], {}, []
    for poly in polygons:
        face = []
        for p in np.asarray(poly, dtype=np.float64):
            key = tuple(np.round(p, 9))
            if key not in index:
                index[key] = len(verts)
                verts.append(tuple(p))
            face.append(index[key])
        faces.append(face)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def mesh_from_segments(name, segments, scene):
    """``scene``'s Lixel mesh ``name`` (new or emptied) holding line segments."""
    mesh = nodes.lixel_mesh(name, scene)
    mesh.clear_geometry()
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3)
    verts = [tuple(p) for p in seg.reshape(-1, 3)]
    edges = [(2 * i, 2 * i + 1) for i in range(len(seg))]
    mesh.from_pydata(verts, edges, [])
    mesh.update()
    return mesh


def baked_items(st) -> list:
    """(object name, kind, 'faces'|'edges', data) for everything bake makes."""
    g = st.geometry
    items = [("Lixel B", "body", "faces", st.body.faces),
             ("Lixel View Frustum", "view_frustum", "faces", hexahedron_faces(g["view_corners"]))]
    for i, faces in enumerate(g["light_faces"]):
        if faces:
            items.append((f"Lixel Light Frustum {i} ({st.setup.maps[i].role})", "light_frustum", "faces", faces))
    if g["warp_corners"] is not None:
        items.append(("Lixel Warp Frustum P", "warp_frustum", "faces", hexahedron_faces(g["warp_corners"])))
    for key, seg in g["vectors"].items():
        items.append((f"Lixel {key}", key, "edges", seg[None]))
    return items


def bake(scene, st) -> list:
    """Create or update the baked objects; remove baked objects this setup no
    longer has (e.g. fewer maps). Returns the objects."""
    made = []
    for name, kind, what, data in baked_items(st):
        mesh = mesh_from_polygons(name, data, scene) if what == "faces" else mesh_from_segments(name, data, scene)
        ob = nodes.debug_object(scene, name, f"{BAKED}:{kind}", mesh)
        ob.display_type = "SOLID" if kind == "body" else "WIRE"
        if kind == "body":
            ob.show_transparent = True
            ob.color = (1.0, 0.55, 0.1, 0.3)
        if hasattr(ob, "visible_shadow"):
            ob.visible_shadow = False
        made.append(ob)
    keep = {ob.name for ob in made}
    coll = nodes.debug_collection(scene)
    for ob in list(coll.objects):
        if str(ob.get(DEBUG_KEY, "")).startswith(BAKED + ":") and ob.name not in keep and is_lixel_made(ob):
            mesh = ob.data
            bpy.data.objects.remove(ob)
            if mesh is not None and mesh.users == 0 and is_lixel_made(mesh):
                bpy.data.meshes.remove(mesh)
    return made


class LIXEL_OT_bake_debug(LixelSceneOperator, bpy.types.Operator):
    """Bake B, the view and light frusta, the warp frustum P and its vectors to meshes in the "Lixel Debug" collection (visible in any render engine and saved with the file; re-baking replaces them)"""

    bl_idname = "lixel.bake_debug"
    bl_label = "Bake Debug Geometry"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    @guarded_operator
    def execute(self, context):
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        made = bake(context.scene, st)
        self.report({"INFO"}, f"Lixel: baked {len(made)} objects into '{nodes.debug_collection(context.scene).name}'")
        return {"FINISHED"}


def linked_note(linked: list) -> str:
    """Why the texel grid leaves ``linked`` objects (what Lixel put on them would not be saved), and the remedy."""
    libraries = ", ".join(sorted({ob.library.name for ob in linked}))
    names = nodes.listed([repr(name) for name in sorted(ob.name for ob in linked)])
    return (f"{names} {'is' if len(linked) == 1 else 'are'} linked from {libraries}: make it local (Object > "
            f"Relations > Make Local > Selected Objects and Data) to change its texel grid")


def workbench_note(overrides: list) -> str:
    """Where the texel grid on ``overrides`` (library overrides, or local objects, whose meshes are not the file's
    own: ``nodes.is_files_own``) shows: the modifier and material do, but Workbench's Attribute colour reads the
    colour attribute the mesh names, which Lixel cannot name on a mesh it would not be saved with."""
    libraries = ", ".join(sorted({(ob.data.library or ob.data.override_library.reference.library).name
                                  for ob in overrides}))
    names = nodes.listed([repr(name) for name in sorted(ob.name for ob in overrides)])
    one = len(overrides) == 1
    return (f"the mesh{'' if one else 'es'} of {names} {'is' if one else 'are'} {libraries}'s: the grid shows in "
            f"Material Preview and Rendered shading, not in Workbench's Attribute colour; for that, make the mesh "
            f"local (Object > Relations > Make Local > Selected Objects and Data)")


def inherited_note(overrides: list) -> str:
    """Why Remove Texel Grid leaves the grids ``overrides`` (library overrides) have from their library's objects: an
    override cannot remove a modifier its reference has (it was removed, and came back when the file was opened)."""
    libraries = ", ".join(sorted({ob.override_library.reference.library.name for ob in overrides}))
    names = nodes.listed([repr(name) for name in sorted(ob.name for ob in overrides)])
    one = len(overrides) == 1
    return (f"{names} {'has its' if one else 'have their'} texel grid from {libraries}, which a library override "
            f"cannot remove (it comes back when the file is opened): switch the '{nodes.TEXEL_MODIFIER}' modifier "
            f"off (Properties > Modifiers: Show in Viewport and Renders), or remove it in {libraries}")


class LIXEL_OT_texel_grid_add(MatrixOperator, bpy.types.Operator):
    """Put the shadow-map texel grid on the selected meshes (a geometry-nodes modifier and material); the light matrices come from the "Lixel Light Matrices" object, updated now"""

    bl_idname = "lixel.texel_grid_add"
    bl_label = "Add Texel Grid"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    map_index: IntProperty(name="Map", default=0, min=0, description="Which shadow map's texels to show")
    remove: BoolProperty(name="Remove", default=False, description="Remove the texel grid instead")

    @guarded_operator
    def execute(self, context):
        meshes = [ob for ob in context.selected_objects if ob.type == "MESH" and ob.get(DEBUG_KEY) is None]
        shapes = [] if self.remove else selected_shapes_not_meshes(context)
        if not meshes:
            self.report({"ERROR"}, f"Lixel: no mesh selected{f' ({not_meshes_note(shapes)})' if shapes else ''}: "
                                   f"select the mesh objects that should show the texel grid")
            return {"CANCELLED"}
        if shapes:
            self.report({"WARNING"}, f"Lixel: the texel grid goes on meshes: {not_meshes_note(shapes)}")
        local = [ob for ob in meshes if ob.library is None]  # a library override keeps the modifier added to it
        if len(local) < len(meshes):  # what Lixel would put on a linked object is not saved with the file
            linked = [ob for ob in meshes if ob.library is not None]
            self.report({"WARNING"} if local else {"ERROR"}, f"Lixel: {linked_note(linked)}")
            meshes = local
            if not meshes:
                return {"CANCELLED"}
        if self.remove:
            # (an appended object's modifiers say is_override_data too: only an override inherits from a library)
            if inherited := [ob for ob in meshes if ob.override_library is not None and getattr(
                    nodes.lixel_modifier(ob, nodes.TEXEL_MODIFIER), "is_override_data", False)]:
                self.report({"WARNING"} if len(inherited) < len(meshes) else {"ERROR"},
                            f"Lixel: {inherited_note(inherited)}")
                meshes = [ob for ob in meshes if ob not in inherited]
                if not meshes:
                    return {"CANCELLED"}
            n = nodes.remove_texel_grids(meshes)
            self.report({"INFO"}, f"Lixel: removed the texel grid from {n} object(s)")
            return {"FINISHED"}
        st = self.fresh_state(context, self.map_index)
        if st is None:
            return {"CANCELLED"}
        carrier = nodes.ensure_carrier(context.scene, st.setup)
        if others := {n: c for n, c in nodes.followers_of_other_carriers(meshes, carrier, context.scene).items()
                      if c[1]}:
            named = nodes.listed([f"{n!r} (followed {followed(*c)})" for n, c in others.items()])
            self.report({"WARNING"}, f"Lixel: {named} "
                                     f"showed another scene's light matrices: an object follows one scene's, this "
                                     f"scene's from now on, in every scene it is in")
        said = []
        for ob in meshes:
            nodes.add_texel_grid(ob, carrier, self.map_index, said)
        self.say(said)
        if overrides := [ob for ob in meshes if not nodes.is_files_own(ob.data)]:
            self.report({"WARNING"}, f"Lixel: {workbench_note(overrides)}")
        self.name_followers_of_missing_maps(carrier, st)
        self.report({"INFO"}, f"Lixel: texel grid of map {self.map_index} on {len(meshes)} object(s)")
        return {"FINISHED"}


class LIXEL_OT_frustum_add(MatrixOperator, bpy.types.Operator):
    """Add an object whose mesh is a shadow map's frustum, built by geometry nodes from the light matrix (it follows the matrix when the setup is synced)"""

    bl_idname = "lixel.frustum_add"
    bl_label = "Add Frustum From Matrix"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    map_index: IntProperty(name="Map", default=0, min=0)

    @guarded_operator
    def execute(self, context):
        st = self.fresh_state(context, self.map_index)
        if st is None:
            return {"CANCELLED"}
        carrier = nodes.ensure_carrier(context.scene, st.setup)
        said = []
        ob = nodes.add_frustum_object(context.scene, carrier, self.map_index, said)
        self.say(said)
        self.name_followers_of_missing_maps(carrier, st)
        note = frustum_note(ob, st.setup.maps[self.map_index].matrix, context.evaluated_depsgraph_get())
        self.report({"INFO"}, f"Lixel: '{ob.name}' follows map {self.map_index}" + (f" ({note})" if note else ""))
        return {"FINISHED"}


def frustum_note(ob, matrix, depsgraph) -> str:
    """Why the frustum object ``ob`` of ``matrix`` is empty, or "" when its group drew the volume. Besides a volume
    through infinity (``finite_clip_volume_corners``, float64), the group's float32 inverse can put a corner that is
    barely in front of the light at w <= 0; it then draws nothing rather than a mirrored box."""
    if len(ob.evaluated_get(depsgraph).data.vertices):
        return ""
    why = ("this map's volume reaches through infinity" if finite_clip_volume_corners(matrix) is None else
           "a corner of this map's volume lies so near infinity that the node group's float32 arithmetic puts it "
           "behind the light")
    return f"empty for now: {why}; the light frustum overlay shows its part around B"


class LIXEL_OT_sync_matrices(MatrixOperator, bpy.types.Operator):
    """Write the current light matrices to the "Lixel Light Matrices" object, so texel grids and frustum objects follow"""

    bl_idname = "lixel.sync_matrices"
    bl_label = "Sync Light Matrices"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    @guarded_operator
    def execute(self, context):
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        self.name_followers_of_missing_maps(nodes.ensure_carrier(context.scene, st.setup), st)
        self.report({"INFO"}, f"Lixel: {len(st.setup.maps)} matrices synced")
        return {"FINISHED"}


classes = (LIXEL_OT_bake_debug, LIXEL_OT_texel_grid_add, LIXEL_OT_frustum_add, LIXEL_OT_sync_matrices)
