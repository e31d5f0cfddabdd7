"""What every Lixel operator shares: the live state of the context's scene, or a
clear report of what is missing (no camera, no light, no mesh)."""
from ...warp.types import WarpError
from .. import live
from ..nodes import listed
from ..properties import ensure_defaults

SHAPED = {"CURVE": "a curve", "SURFACE": "a surface", "META": "a metaball", "FONT": "a text"}
"""Object types that show surfaces without being meshes (what they are called in a message)."""


def selected_shapes_not_meshes(context) -> list:
    """The selected objects that show surfaces but are not meshes (:data:`SHAPED`, and empties instancing a
    collection), which the operators taking meshes leave out."""
    return [ob for ob in context.selected_objects if ob.type in SHAPED or (
        ob.type == "EMPTY" and ob.instance_type == "COLLECTION" and ob.instance_collection is not None)]


def not_meshes_note(obs: list) -> str:
    """Names ``obs`` (:func:`selected_shapes_not_meshes`) as what they are, and how to make meshes of them."""
    named = listed([f"'{ob.name}' ({SHAPED.get(ob.type, 'a collection instance')})" for ob in obs])
    how = [hint for hint, kinds in (("Object > Convert > Mesh makes meshes of curves, surfaces, metaballs and texts",
                                     SHAPED), ("Object > Apply > Make Instances Real, of an instance's objects",
                                               ("EMPTY",))) if any(ob.type in kinds for ob in obs)]
    return f"{named} {'is not a mesh' if len(obs) == 1 else 'are not meshes'} ({'; '.join(how)})"


def scene_poll(cls, context) -> bool:
    """A scene with Lixel settings (the add-on registered)."""
    if context.scene is None or getattr(context.scene, "lixel", None) is None:
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set("Lixel needs a scene")
        return False
    return True


def editable_scene_poll(cls, context) -> bool:
    """:func:`scene_poll`, and the scene is the file's own: a scene linked from a library is read-only (what an
    operator added to it could not be saved, and Blender refuses to link objects into its collections)."""
    if not scene_poll(cls, context):
        return False
    library = context.scene.library
    if library is not None:
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set(f"Scene '{context.scene.name}' is linked from {library.name} and cannot be changed "
                                 f"here: make it local (Outliner, Blender File view: right-click it > Make Local) "
                                 f"or change it in {library.name}")
        return False
    return True


def active_object(context):
    view_layer = getattr(context, "view_layer", None)
    return view_layer.objects.active if view_layer is not None else None


def current_state(op, context, force: bool = False):
    """The scene's live state, computed if needed (``force``: recompute all).
    Reports the error and returns None when something is missing."""
    scene = context.scene
    st = live.state(scene)
    moved = live.follow(scene, live.local_camera(context))     # the 3D view's Local Camera, as its F12 renders
    if force or moved or st is None or st.error or st.provisional:   # a moving view's cascade: the full one
        depsgraph = context.evaluated_depsgraph_get()
        try:
            st = live.update(scene, depsgraph, active=active_object(context))
        except WarpError as exc:  # settings the warp core rejects (e.g. map size)
            op.report({"ERROR"}, f"Lixel: {exc}")
            return None
    if st.error:
        op.report({"ERROR"}, f"Lixel: {st.error}")
        return None
    if st.note:
        op.report({"WARNING"}, f"Lixel: {st.note}")
    return st


def initialise(context) -> None:
    ensure_defaults(context.scene)


class LixelSceneOperator:
    """Mixin for operators on the context scene's Lixel setup: ``poll`` needs a
    scene with Lixel settings, ``fresh_state`` recomputes the setup or reports
    what is missing (and returns None). ``changes_scene``: the operator writes the scene's settings or adds to it,
    so it needs a scene of the file's own (:func:`editable_scene_poll`)."""

    changes_scene = False

    @classmethod
    def poll(cls, context):
        return editable_scene_poll(cls, context) if cls.changes_scene else scene_poll(cls, context)

    def fresh_state(self, context, map_index: int | None = None):
        """The recomputed state; None, reported, when something is missing or the setup has no map ``map_index``."""
        initialise(context)
        st = current_state(self, context, force=True)
        if st is not None and map_index is not None and map_index >= len(st.setup.maps):
            self.report({"ERROR"}, f"Lixel: map {map_index} does not exist; this setup has {len(st.setup.maps)} map(s)")
            return None
        return st
