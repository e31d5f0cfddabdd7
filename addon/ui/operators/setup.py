"""Refresh the setup, reset settings to the preferences, toggle overlays."""
import bpy
from bpy.props import EnumProperty

from ...guard import guarded_operator
from ...settings import LixelSettings
from .. import live, overlays
from ..properties import OVERLAYS, take_preferences
from .common import LixelSceneOperator, current_state, initialise


class LIXEL_OT_refresh(LixelSceneOperator, bpy.types.Operator):
    """Compute (or recompute) the shadow setup for the scene camera and the Lixel light"""

    bl_idname = "lixel.refresh"
    bl_label = "Refresh Setup"
    bl_options = {"REGISTER", "UNDO"}  # a scene's first refresh writes its settings

    @guarded_operator
    def execute(self, context):
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        d = st.setup.diagnostics
        self.report({"INFO"}, f"Lixel {st.method_used}: {len(st.setup.maps)} map(s), B has "
                              f"{len(d.body_vertices)} vertices ({st.total_ms():.1f} ms)")
        overlays.sync_handlers(context)
        return {"FINISHED"}


class LIXEL_OT_reset_settings(LixelSceneOperator, bpy.types.Operator):
    """Reset this scene's Lixel settings to the add-on preferences' defaults (the light and planes are kept)"""

    bl_idname = "lixel.reset_settings"
    bl_label = "Reset to Preferences"
    bl_options = {"REGISTER", "UNDO"}
    changes_scene = True

    @guarded_operator
    def execute(self, context):
        props = context.scene.lixel
        props.from_settings(LixelSettings(), planes=False)   # where the preferences are not available
        take_preferences(props)
        self.report({"INFO"}, f"Lixel settings reset to the preferences (method {props.method})")
        return {"FINISHED"}


class LIXEL_OT_toggle_overlay(LixelSceneOperator, bpy.types.Operator):
    """Show or hide a Lixel viewport overlay"""

    bl_idname = "lixel.toggle_overlay"
    bl_label = "Toggle Lixel Overlay"
    bl_options = {"REGISTER", "UNDO"}

    overlay: EnumProperty(name="Overlay", items=[(name, label, desc) for name, label, desc in OVERLAYS])

    @classmethod
    def description(cls, context, properties):
        for name, label, desc in OVERLAYS:
            if name == properties.overlay:
                return f"Show or hide: {desc}"
        return cls.__doc__

    @guarded_operator
    def execute(self, context):
        initialise(context)
        props = context.scene.lixel
        on = not getattr(props, self.overlay)
        setattr(props, self.overlay, on)
        label = dict((n, l) for n, l, _ in OVERLAYS)[self.overlay]
        if on:
            st = current_state(self, context, force=live.state(context.scene) is None)
            if st is None:
                self.report({"WARNING"}, f"Lixel: {label} is on but there is nothing to show yet")
            elif self.overlay in overlays.GPU_OVERLAYS and overlays.gpu_pipeline() is None:
                self.report({"WARNING"}, f"Lixel: {label} needs the gpu pipeline, which is not available")
        overlays.sync_handlers(context)
        return {"FINISHED"}


classes = (LIXEL_OT_refresh, LIXEL_OT_reset_settings, LIXEL_OT_toggle_overlay)
