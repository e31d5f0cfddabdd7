"""The "Lixel" tab of the 3D viewport's sidebar: settings, live readouts,
overlay toggles and the operators' buttons.

Draw code only reads (``ensure_defaults`` and computing are left to the
operators and handlers); a scene never computed shows a Refresh button.
"""
import textwrap

import bpy

from ..guard import guarded_draw
from ..warp.methods import VISIBLE_RANGE_METHODS
from . import live, overlays
from .properties import CASCADE_METHODS, CASCADE_SETTINGS, LAMBDA_METHODS, N_OPT_METHODS, OVERLAYS, PLANE_METHODS

WARP_METHODS = N_OPT_METHODS + LAMBDA_METHODS
"""Methods with a perspective warp (V_P, middle vector, Δz apply)."""


def method_parameters(method: str, light_type: str = "") -> tuple[str, ...]:
    """The ``scene.lixel`` properties that matter for ``method`` (and the light type)."""
    names = ["shadow_map_size", "focus", "linear_z"]
    if method == "uniform":
        names.append("texel_snapping")
    if method in WARP_METHODS:
        names.append("delta_z")
    if method in VISIBLE_RANGE_METHODS:     # (PSM's d_R and the cascade's splits read it too)
        names += ["use_visible_depth_range", "visible_depth_range"]
    if method in WARP_METHODS:
        names.append("middle_vector")
    if method in LAMBDA_METHODS:
        names += ["use_lambda", "lam"]
    if method in WARP_METHODS:
        names.append("lambda_guard")
    if method in PLANE_METHODS:
        names += ["plane_budget", "plane_twist"]
    if method in CASCADE_METHODS:
        names += list(CASCADE_SETTINGS)
    if light_type in ("POINT", ""):
        names.append("max_frustum_angle")
    return tuple(names)


LINE_CHARS = 42
"""Characters of a message line that fit the sidebar at its default width."""


READOUT_CHARS = 32
"""A readout value longer than this is wrapped below its label instead of sharing the label's row."""


def wrapped_label(layout, text: str, icon: str) -> None:
    """``text`` in full as lines of at most :data:`LINE_CHARS` (Blender cuts a long label off at the panel's
    edge), ``icon`` on the first."""
    lines = textwrap.wrap(" ".join(text.split()), LINE_CHARS, break_long_words=False, break_on_hyphens=False)
    for i, line in enumerate(lines or [""]):
        layout.label(text=line, icon=icon if i == 0 else "BLANK1")


def draw_notes(layout, notes) -> None:
    """The scene's notes (``LiveState.notes``, as the live state last gathered them: drawing computes nothing),
    each in full (:func:`wrapped_label`) behind an alert icon: what a render with Lixel warns about."""
    for note in notes:
        wrapped_label(layout.column(align=True), note, "ERROR")


def split_layout(layout):
    """``layout`` with properties in split rows, without animation decorators."""
    layout.use_property_split, layout.use_property_decorate = True, False
    return layout


class LixelPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lixel"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and getattr(context.scene, "lixel", None) is not None


class LIXEL_PT_main(LixelPanel, bpy.types.Panel):
    """Lixel: warped shadow maps for the scene camera and one light"""

    bl_label = "Lixel"
    bl_idname = "LIXEL_PT_main"

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = split_layout(self.layout)
        scene = context.scene
        props = scene.lixel
        col = layout.column()
        col.prop(props, "light", text="Light")
        if props.light is None:
            st = live.state(scene)
            col.label(text=f"Using: {st.light_name}" if st is not None and st.light_name else
                      "Using: the active light, else the first sun", icon="INFO")
        col.prop(props, "method")
        if scene.camera is None and live.local_camera(context) is None:
            col.label(text="The scene has no camera: add one and make it active", icon="ERROR")
        row = layout.row(align=True)
        row.operator("lixel.refresh", icon="FILE_REFRESH")
        row.prop(props, "live_update", text="", icon="REC" if props.live_update else "PAUSE", toggle=True)
        st = live.state(scene)
        if st is not None and st.error:
            wrapped_label(layout.box(), st.error, "ERROR")
        elif st is not None and st.note:
            wrapped_label(layout.column(align=True), st.note, "INFO")
        if st is not None and st.notes:
            draw_notes(layout.box(), st.notes)
        if not props.initialised:
            box = layout.box()
            box.label(text="Not set up: renders with the preference defaults", icon="PREFERENCES")
            box.operator("lixel.reset_settings", text="Set Up From Preferences")


class LIXEL_PT_method(LixelPanel, bpy.types.Panel):
    bl_label = "Method"
    bl_parent_id = "LIXEL_PT_main"

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = split_layout(self.layout)
        props = context.scene.lixel
        light = props.light
        light_type = light.data.type if light is not None and light.type == "LIGHT" else ""
        col = layout.column()
        for name in method_parameters(props.method, light_type):
            sub = col.row()
            if name == "visible_depth_range":
                sub.enabled = props.use_visible_depth_range
            elif name == "lam":
                sub.enabled = props.use_lambda
            elif name == "cascade_warp":
                sub.enabled = not props.cascade_stable        # a stable cascade's splits are uniform maps
            sub.prop(props, name)
        if props.method in PLANE_METHODS:
            draw_planes(layout, props)


def draw_planes(layout, props) -> None:
    box = layout.box()
    box.label(text=f"Planes of Interest ({len(props.planes)})")
    for i, p in enumerate(props.planes):
        row = box.row(align=True)
        row.label(text=p.label(i))
        op = row.operator("lixel.plane_remove", text="", icon="X")
        op.index = i
    if not len(props.planes):
        box.label(text="None: plane_optimal takes the flat receiver top seen most", icon="INFO")
    row = box.row(align=True)
    row.operator("lixel.planes_from_selection", text="From Selection", icon="RESTRICT_SELECT_OFF")
    op = row.operator("lixel.planes_from_selection", text="Add Selection", icon="ADD")
    op.append = True


class LIXEL_PT_shadows(LixelPanel, bpy.types.Panel):
    bl_label = "Shadows"
    bl_parent_id = "LIXEL_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = split_layout(self.layout)
        props = context.scene.lixel
        col = layout.column()
        col.prop(props, "bias_mode")
        sub = col.column()
        sub.enabled = props.bias_mode in ("CONSTANT", "CONSTANT_SLOPE", "RECEIVER_PLANE", "NORMAL_OFFSET")
        sub.prop(props, "constant_bias")
        sub = col.column()
        sub.enabled = props.bias_mode in ("SLOPE", "CONSTANT_SLOPE")
        sub.prop(props, "slope_bias")
        sub = col.column()
        sub.enabled = props.bias_mode == "NORMAL_OFFSET"
        sub.prop(props, "normal_offset")
        col.prop(props, "back_faces")
        col.separator()
        col.prop(props, "pcf_kernel")
        sub = col.column()
        sub.enabled = props.pcf_kernel == 2 and props.mdsm_depths == 1
        sub.prop(props, "revectorize")
        col.prop(props, "mdsm_depths")
        sub = col.column()
        sub.enabled = props.mdsm_depths > 1
        sub.prop(props, "mdsm_selection")
        sub.prop(props, "mdsm_neighbourhood")
        col.prop(props, "eye_blur")


class LIXEL_PT_readouts(LixelPanel, bpy.types.Panel):
    bl_label = "Readouts"
    bl_parent_id = "LIXEL_PT_main"

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = self.layout
        st = live.state(context.scene)
        if st is None:
            layout.label(text="Not computed yet: press Refresh", icon="INFO")
            return
        col = layout.column(align=True)
        for label, value in live.readouts(st):
            if len(value) > READOUT_CHARS:          # a sentence (an error, a fallback's reason): wrapped, full width
                col.label(text=label)
                wrapped_label(col, value, "BLANK1")
                continue
            row = col.row()
            split = row.split(factor=0.4)
            split.label(text=label)
            split.label(text=value)


class LIXEL_PT_overlays(LixelPanel, bpy.types.Panel):
    bl_label = "Overlays"
    bl_parent_id = "LIXEL_PT_main"

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = self.layout
        props = context.scene.lixel
        col = layout.column(align=True)
        pipeline = overlays.gpu_pipeline() is not None
        for name, label, _desc in OVERLAYS:
            row = col.row(align=True)
            if name in overlays.GPU_OVERLAYS and not pipeline:
                row.enabled = False
            op = row.operator("lixel.toggle_overlay", text=label, depress=bool(getattr(props, name)),
                              icon="HIDE_OFF" if getattr(props, name) else "HIDE_ON")
            op.overlay = name
        col.separator()
        col.prop(props, "body_alpha", slider=True)
        col.prop(props, "map_pip_size")


class LIXEL_PT_tools(LixelPanel, bpy.types.Panel):
    bl_label = "Tools"
    bl_parent_id = "LIXEL_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    @guarded_draw("drawing Lixel's panel")
    def draw(self, context):
        layout = self.layout
        col = layout.column(align=True)
        col.operator("lixel.compare", icon="IMAGE_REFERENCE")
        col.operator("lixel.export_json", icon="EXPORT")
        col.operator("lixel.overlay_snapshot", icon="RENDER_STILL")
        col.separator()
        col.operator("lixel.bake_debug", icon="OUTLINER_COLLECTION")
        col.operator("lixel.texel_grid_add", icon="TEXTURE")
        op = col.operator("lixel.texel_grid_add", text="Remove Texel Grid", icon="REMOVE")
        op.remove = True
        col.operator("lixel.frustum_add", icon="CONE")
        col.operator("lixel.sync_matrices", icon="FILE_REFRESH")
        col.separator()
        col.operator("lixel.reset_settings", icon="PREFERENCES")


classes = (LIXEL_PT_main, LIXEL_PT_method, LIXEL_PT_shadows, LIXEL_PT_readouts, LIXEL_PT_overlays, LIXEL_PT_tools)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(classes)
