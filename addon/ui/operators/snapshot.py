"""Save the viewport overlays as PNG: from the scene camera, from an outside
observer that sees the whole setup, and (run from a 3D viewport) from that
viewport's own view. Drawn off-screen by the viewport's draw code
(:mod:`..snapshot`), so it also works in background mode."""
import os

import bpy
import numpy as np
from bpy.props import IntProperty, StringProperty

from ...guard import guarded_operator
from .common import LixelSceneOperator

OBSERVER_OVERLAYS = ("body", "frusta", "warp")


def unused_paths(directory: str, names: list) -> list:
    """``directory``/overlay_NAME.png for each of ``names``, numbered (overlay_NAME_2.png, ...) as one set where any
    of them is there already: a second snapshot, of another method say, keeps the first."""
    for k in range(1, 10_000):
        paths = [os.path.join(directory, f"overlay_{n}{'' if k == 1 else f'_{k}'}.png") for n in names]
        if not any(os.path.exists(p) for p in paths):
            return paths
    raise OSError(f"10,000 snapshots in '{directory}' already")


def receiver_overlays(props) -> list:
    """The receiver overlay the scene shows (texel grid and/or heatmap), the heatmap when it shows neither."""
    shown = [n for n in ("texels", "footprint") if getattr(props, f"show_{n}")]
    return shown or ["footprint"]


class LIXEL_OT_overlay_snapshot(LixelSceneOperator, bpy.types.Operator):
    """Save Lixel's overlays as PNG pictures: from the scene camera, from an outside observer that sees the view frustum, the light frusta, B and the warp frustum, and from this viewport's view"""

    bl_idname = "lixel.overlay_snapshot"
    bl_label = "Save Overlay Snapshots"
    bl_options = {"REGISTER", "UNDO"}  # a scene's first snapshot writes its settings

    directory: StringProperty(name="Folder", subtype="DIR_PATH", description="Folder for the PNG files")
    width: IntProperty(name="Width", default=1280, min=64, max=8192, description="Picture width in pixels")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    @guarded_operator
    def execute(self, context):
        from ...gpu.context import GPUUnavailableError, ensure_gpu_context
        from .. import renders, snapshot
        if not self.directory:
            self.report({"ERROR"}, "Lixel: choose a folder for the overlay snapshots")
            return {"CANCELLED"}
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        try:
            ensure_gpu_context()
        except GPUUnavailableError as exc:
            self.report({"ERROR"}, f"Lixel: {exc}")
            return {"CANCELLED"}
        props = context.scene.lixel
        receivers = receiver_overlays(props)
        views = [("camera", snapshot.camera_view_projection(st.view), renders.fit_resolution(st.view.resolution,
                                                                                           self.width), receivers)]
        w, h = self.width, max(1, round(self.width * 0.625))
        observer, notes = snapshot.observer_view_projection(st.geometry, st.view, w / h, scene=context.scene)
        views.append(("observer", observer, (w, h), list(OBSERVER_OVERLAYS) + receivers[-1:]))
        region = getattr(context, "region_data", None)
        if region is not None and context.region is not None:
            shown = [n for n in ("body", "frusta", "warp", "texels", "footprint") if getattr(props, f"show_{n}")]
            size = (context.region.width, context.region.height)
            views.append(("view", np.array(region.perspective_matrix, dtype=np.float64), size, shown or receivers))
        try:
            os.makedirs(bpy.path.abspath(self.directory), exist_ok=True)
        except OSError as exc:
            self.report({"ERROR"}, f"Lixel: cannot make the folder '{self.directory}': {exc.strerror}")
            return {"CANCELLED"}
        written = []
        paths = unused_paths(bpy.path.abspath(self.directory), [name for name, *_ in views])
        for (name, view_projection, size, names), path in zip(views, paths):
            img = snapshot.draw_snapshot(context.scene, st, snapshot.OverlayFlags.of(names), view_projection, size)
            try:
                renders.save_image(img, path, linear=False)
            except OSError as exc:
                self.report({"ERROR"}, f"Lixel: cannot write '{path}': {exc.strerror}")
                return {"CANCELLED"}
            written.append(os.path.basename(path))
        # what the observer's picture leaves out (its lines run out of the picture), as the script says it
        left_out = f"; the observer's picture leaves out: {'; '.join(notes)}" if notes else ""
        self.report({"INFO"}, f"Lixel: saved {', '.join(written)} in {self.directory}{left_out}")
        return {"FINISHED"}


classes = (LIXEL_OT_overlay_snapshot,)
