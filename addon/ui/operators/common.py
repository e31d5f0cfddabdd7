"""What every Lixel operator shares: the live state of the context's scene, or a
clear report of what is missing (no camera, no light, no mesh)."""
from ...warp.types import WarpError
from .. import live
from ..properties import ensure_defaults


def scene_poll(cls, context) -> bool:
    """A scene with Lixel settings (the add-on registered)."""
    if context.scene is None or getattr(context.scene, "lixel", None) is None:
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set("Lixel needs a scene")
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
    if force or moved or st is None or st.error:
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
    what is missing (and returns None)."""

    @classmethod
    def poll(cls, context):
        return scene_poll(cls, context)

    def fresh_state(self, context, map_index: int | None = None):
        """The recomputed state; None, reported, when something is missing or the setup has no map ``map_index``."""
        initialise(context)
        st = current_state(self, context, force=True)
        if st is not None and map_index is not None and map_index >= len(st.setup.maps):
            self.report({"ERROR"}, f"Lixel: map {map_index} does not exist; this setup has {len(st.setup.maps)} map(s)")
            return None
        return st
