"""Export the light matrices and diagnostics to JSON (the CLI's format), and
compare the methods for the current view."""
import json
import os

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from ...cli.output import setup_json, write_text
from ...guard import guarded_operator
from ...scene.owned import lixel_datablock
from ...warp import METHODS
from .. import live, overlays
from .common import LixelSceneOperator

COMPARISON_TEXT = "Lixel Comparison"
BLEND_RELATIVE = {"PATH_SUPPORTS_BLEND_RELATIVE"} \
    if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties else set()
"""The path option that tells Blender (4.5 on) a "//" path is meant: execute() resolves it beside the .blend file."""
COMPARISON_IMAGE = "Lixel Comparison"


def export_document(st, all_methods: bool) -> dict:
    """The CLI's JSON: ``{"maps": [...], "diagnostics": {...}}`` for the scene's
    method, or ``{"methods": {name: {...}}}`` for every method (like
    ``python -m addon.warp --method all``)."""
    if not all_methods:
        return setup_json(st.setup)
    out = {}
    for row in live.compare_methods(st):
        if "error" in row:
            out[row["method"]] = {"maps": [], "diagnostics": {"method": row["method"], "error": row["error"],
                                                              "fallbacks": []}}
        else:
            out[row["method"]] = setup_json(row["setup"])
    return {"methods": out}


class LIXEL_OT_export_json(LixelSceneOperator, bpy.types.Operator, ExportHelper):
    """Export the light matrices and diagnostics of the current setup to JSON, in the format of the command line (python -m addon.warp)"""

    bl_idname = "lixel.export_json"
    bl_label = "Export Matrices (JSON)"
    bl_options = {"REGISTER", "UNDO"}  # a scene's first export writes its settings

    filename_ext = ".json"
    filepath: StringProperty(name="File Path", description="Filepath used for exporting the file", maxlen=1024,
                             subtype="FILE_PATH", options=BLEND_RELATIVE)
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    all_methods: BoolProperty(name="All Methods", default=False,
                              description="Export every method ({\"methods\": {...}}) instead of the scene's")
    indent: BoolProperty(name="Pretty", default=True, description="Indent the JSON")

    @guarded_operator
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if not os.path.basename(path) or os.path.isdir(path):   # was written as a hidden '.json' there
            self.report({"ERROR"}, f"Lixel: no file name given{f' (only the folder {path})' if path else ''}: name "
                                   f"the JSON file to export to, as Blender's exporters ask")
            return {"CANCELLED"}
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        doc = export_document(st, self.all_methods)
        # "//name.json": beside the .blend file, as Blender's paths are. Called from Python (no file browser to add
        # the extension), a path without ".json" gets it, as Blender's exporters do: it never overwrites a .blend.
        path = bpy.path.ensure_ext(path, self.filename_ext)
        try:   # whole or not at all: a failed write leaves the file that was there
            write_text(path, json.dumps(doc, indent=2 if self.indent else None) + "\n")
        except OSError as exc:
            self.report({"ERROR"}, f"Lixel: cannot write '{path}': {exc.strerror}")
            return {"CANCELLED"}
        what = "every method" if self.all_methods else f"{len(st.setup.maps)} map(s) of {st.method_used}"
        self.report({"INFO"}, f"Lixel: exported {what} to {path}")
        return {"FINISHED"}


class LIXEL_OT_compare(LixelSceneOperator, bpy.types.Operator):
    """Compare every method for the current view: θ, γ, n_opt, λ, maps and the texel footprint, written to the "Lixel Comparison" text, plus shadow renders when the gpu pipeline is available"""

    bl_idname = "lixel.compare"
    bl_label = "Compare Methods"
    bl_options = {"REGISTER", "UNDO"}

    longest_side: IntProperty(name="Picture Size", default=320, min=16, max=4096,
                              description="Longer side of each method's picture in the comparison image")

    @guarded_operator
    def execute(self, context):
        st = self.fresh_state(context)
        if st is None:
            return {"CANCELLED"}
        rows = live.compare_methods(st)
        table = live.comparison_table(rows, context.scene)
        note = ""
        if overlays.gpu_pipeline() is None:
            note = ("\n\nShadow renders of each method need the gpu pipeline (addon/gpu), which is not available "
                    "in this build: only the numbers are compared.")
        else:
            from .. import renders
            from ...warp.types import WarpError
            try:
                picture, names = renders.compare_renders(st, context.evaluated_depsgraph_get(), rows,
                                                         longest=self.longest_side)
                img = renders.to_image(COMPARISON_IMAGE, picture, keep=True)
                note = (f"\n\nImage '{img.name}': the camera view rendered with each method, left to right "
                        f"and top to bottom: {', '.join(names)}.")
            except (WarpError, ValueError) as exc:
                note = f"\n\nNo comparison render: {exc}"
                self.report({"WARNING"}, f"Lixel: no comparison render: {exc}")
        text, _ = lixel_datablock(bpy.data.texts, COMPARISON_TEXT)
        text.clear()
        camera = live.followed_camera(context.scene)            # the 3D view's Local Camera, else the scene's
        text.write(f"Lixel comparison, scene '{context.scene.name}', camera '{camera.name}', "
                   f"light '{st.light_name}', {len(METHODS)} method(s)\n"
                   "texel px = screen pixels one shadow-map texel spans, on surfaces in view facing halfway between "
                   "camera and light (≤ 1: no perspective aliasing)\n\n" + table + note + "\n")
        best = [r for r in rows if "error" not in r and r["footprint_max_px"] is not None]
        if best:
            b = min(best, key=lambda r: r["footprint_max_px"])
            self.report({"INFO"}, f"Lixel: compared {len(rows)} methods; smallest worst-case footprint: "
                                  f"{b['method']} ({b['footprint_max_px']:.3g} px). See the '{text.name}' text")
        else:
            self.report({"INFO"}, f"Lixel: compared {len(rows)} methods. See the '{text.name}' text")
        return {"FINISHED"}


classes = (LIXEL_OT_export_json, LIXEL_OT_compare)
