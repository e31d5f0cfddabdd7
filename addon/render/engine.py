"""The Lixel render engine: F12, ``blender -b file.blend -E LIXEL -f 1`` and
``bpy.ops.render.render()`` render the scene's camera view shaded with Lixel's
warped shadow maps.

Holdouts (Object properties > Visibility > Holdout, a collection's Holdout in the view layer, or a surface whose
materials are all a Holdout shader: ``addon.scene.materials``) render as Cycles renders them: a transparent hole, (0,
0, 0, 0) in Combined with Film Transparent on or off, empty in the other passes (no shadow, black footprint), that
still hides what is behind it and still casts its shadow (``addon.scene.instances.holdout_test``;
``ShadowFrame.shade``).

Light Linking and Shadow Linking of the light it renders (Object properties > Shading) are followed as Cycles follows
them: an object the light does not light gets the world's light alone and no shadow of it in the Shadow pass, but
still hides what is behind it and casts the shadow; an object Shadow Linking leaves out casts none of that light's
(``addon.scene.linking``). The warp is still fitted to every caster, those left out included.

Passes: Combined, and per view layer (View Layer properties > Lixel Passes,
``view_layer.lixel_passes``) "Shadow" (0 lit .. 1 fully shadowed; on by
default), "Footprint" (the shadow-map texel footprint heatmap, see
``gpu_shaders/shade_frag.glsl``) and "Shadow Map" (the first map's window
depth, resampled to the render size), both off by default like Blender's own
extra passes: each costs the frame a target, a read-back and the memory of
the pass. The frame stays on the GPU until the passes asked for are read
back, once.
Nothing is kept after a render: the result (every map at full resolution,
timings, counts; a 16384² map alone is 1 GiB) is freed when the render ends.
Code that wants it (tests, tools) collects it with :func:`watch_renders`.

Settings come from ``scene.lixel.to_settings()`` when the Lixel properties are
registered, else ``LixelSettings()`` defaults. Bad input (no camera, no
supported light, nothing to render, no GPU) ends the render with a
``self.report({'ERROR'}, ...)`` naming the problem, never a traceback.
"""
from __future__ import annotations

import dataclasses
import logging
import time
from contextlib import contextmanager
from typing import Optional

import bpy
import numpy as np

from ..gpu.blas import one_blas_thread
from ..guard import guarded_draw, user_message
from ..scene.owned import is_debug_object
from ..settings import LixelSettings
from ..warp import compute, focused_body
from ..warp.frame import light_frames
from ..warp.methods import METHODS, reads_surface
from ..warp.types import Diagnostics, EmptyBodyError, Light, ShadowMap, ShadowSetup, WarpError
from .warp_cache import shared_warps

log = logging.getLogger(__name__)

GUARDED = ("lispsm", "gmnpr", "glpr", "psm", "cascade")
"""The methods whose warp strength the λ guard can keep no worse than the uniform map (docs/papers.md, "The λ
guard"), the cascade through its splits' warps."""

ONE_MAP_TURNS = ("psm", "lispsm", "gmnpr", "glpr")
"""The methods that turn a one-map setup's texel axes off the first look's edges (``warp_frustum.edge_turned``): for
a point light that turn is all their first look serves, so ``fit_warp`` skips it where the light needs several cube
faces (90-120 ms of a cold frame on point_low_in_view)."""


def looks_for_edges(method: str, options, light) -> bool:
    """Whether ``fit_warp`` takes the first look at the shadow edges (``shadow_edges``): where ``method``'s λ guard
    acts, for its weights (``weighs_edges``, not a point light's), the cascade's map pick and the one-map turns of PSM,
    LiSPSM, GMNPR and GLPR (``warp_frustum.edge_turned``), which read the edges' directions through
    ``partition.receivers.filter_losses`` under every kind of light (docs/papers.md, "A pick that sees the edges'
    directions", "family, session 23"), and plane_optimal's default plane (its share of the edges:
    ``plane_optimal.planes_of_interest``)."""
    if options.focus == "visible" and method == "plane_optimal":
        return not options.planes
    if options.focus != "visible" or method not in GUARDED:
        return False
    if method == "cascade":
        return options.lambda_guard == "all" and not options.cascade_stable and options.cascade_warp != "uniform"
    return options.lambda_guard in ("all", method)


def weighs_edges(method: str, options, light) -> bool:
    """Whether ``method``'s λ guard weighs where the first look's shadow edges fall on what is seen (``fit_warp``):
    not for a point light, whose warped cube faces rendered worse with the edges (docs/papers.md, the λ guard, part
    7; why is not known)."""
    return light.type != "POINT" and method in GUARDED and looks_for_edges(method, options, light)

EXTRA_PASSES = (
    # name, channels, channel ids, compositor socket type, view-layer switch, RenderResult image
    ("Shadow", 1, "X", "VALUE", "shadow", "shadow_mask"),
    ("Footprint", 4, "RGBA", "COLOR", "footprint", "footprint_heatmap"),
    ("Shadow Map", 1, "Z", "VALUE", "shadow_map", "shadow_map_preview"),
)


def _passes_changed(self, context):
    view_layer = getattr(context, "view_layer", None)
    if view_layer is not None:
        view_layer.update_render_passes()


class LIXEL_PG_passes(bpy.types.PropertyGroup):
    """Which of Lixel's own render passes a view layer gets (besides Combined)."""

    shadow: bpy.props.BoolProperty(
        name="Shadow", default=True, update=_passes_changed,
        description="The shadow term: 0 lit .. 1 fully shadowed (after the eye-space blur)")
    footprint: bpy.props.BoolProperty(
        name="Footprint", default=False, update=_passes_changed,
        description="Shadow-map texels per pixel as colours: red undersampled, green one, blue oversampled")
    shadow_map: bpy.props.BoolProperty(
        name="Shadow Map", default=False, update=_passes_changed,
        description="The first shadow map's window depth, resampled to the render size")


def enabled_passes(view_layer) -> list:
    """The :data:`EXTRA_PASSES` rows switched on for ``view_layer`` (all of them
    when the switches are not registered)."""
    switches = getattr(view_layer, "lixel_passes", None) if view_layer is not None else None
    return [row for row in EXTRA_PASSES if switches is None or getattr(switches, row[4])]


class LIXEL_PT_view_layer_passes(bpy.types.Panel):
    bl_label = "Lixel Passes"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "view_layer"
    COMPAT_ENGINES = {"LIXEL"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    @guarded_draw("drawing Lixel's passes panel")
    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        switches = context.view_layer.lixel_passes
        col = layout.column(heading="Include")
        for row in EXTRA_PASSES:
            col.prop(switches, row[4])

_watchers: list = []


@contextmanager
def watch_renders(read=()):
    """Collect what each engine render inside the block produced, in order: a
    list of :func:`render_depsgraph` dicts, with the ``warnings`` it reported. The engine itself keeps nothing
    between renders; only the caller's list holds the results, for as long as
    the caller keeps it. ``read``: images to read back besides the engine's
    passes (``addon.gpu.result.RenderResult`` names, e.g. ``{"covered"}``)."""
    got: list = []
    entry = (got, frozenset(read))
    _watchers.append(entry)
    try:
        yield got
    finally:
        _watchers.remove(entry)


def scene_settings(scene) -> LixelSettings:
    """``scene.lixel.to_settings()`` if the Lixel properties exist, else the defaults."""
    props = getattr(scene, "lixel", None)
    if props is not None and hasattr(props, "to_settings"):
        return props.to_settings()
    return LixelSettings()


def no_shadow_setup(method: str) -> ShadowSetup:
    """A setup whose single 1x1 map serves no point (its w is always -1): the
    shading pass then lights everything without shadows."""
    none = np.zeros((4, 4))
    none[3, 3] = -1.0
    return ShadowSetup([ShadowMap(none, (1, 1), role="none")], Diagnostics(method))


def first_look(frame, visible, body, light, bounds, options, method: str):
    """``visible`` with the first look's shadow edges (``shadow_edges``) for ``method`` where ``looks_for_edges``:
    their directions, and their per-tile weights only where the λ guard weighs them (``weighs_edges``)."""
    from ..gpu.visibility import shadow_edges
    seen = shadow_edges(frame, visible, body, light, bounds, options)
    if weighs_edges(method, options, light):
        return seen
    return dataclasses.replace(seen, tiles=dataclasses.replace(seen.tiles, edges=None))


def fit_warp(frame, light, bounds, options, method: str):
    """B and the warp for ``frame`` (a ``ShadowFrame`` whose view is the
    camera's): B fitted to what the frame's pre-pass saw when ``options.focus``
    is "visible", to the view frustum otherwise; where the λ guard acts
    (``looks_for_edges``), also where shadow edges fall on what is seen
    (``shadow_edges``, a coarse first look; the guard weighs them only where
    ``weighs_edges``). Returns (body, setup, seconds spent reading the visible
    region, or None). Raises ``EmptyBodyError``."""
    from ..gpu.visibility import region_from_frame
    visible = seconds = None
    look = looks_for_edges(method, options, light)
    if options.focus == "visible":
        visible, seconds = region_from_frame(frame, surface=reads_surface(method, options) or look)
    body = focused_body(frame.view, light, bounds, options, visible)
    if look and light.type == "POINT" and method in ONE_MAP_TURNS:     # the look serves only the one-map turn
        look = len(light_frames(frame.view, light, body, options)) == 1
    if look:
        t = time.perf_counter()
        body = dataclasses.replace(body, visible=first_look(frame, visible, body, light, bounds, options, method))
        seconds += time.perf_counter() - t
    return body, compute(method, frame.view, light, bounds, options, body=body), seconds


@one_blas_thread()
def render_depsgraph(depsgraph, resolution: Optional[tuple[int, int]] = None, settings: Optional[LixelSettings] = None,
                     warnings: Optional[list] = None, read=None, timed: bool = True, targets=None,
                     camera=None, eye=None) -> dict:
    """Describe, compute and render an evaluated scene (what the engine does);
    usable by scripts and operators. Needs a GPU context. Returns ``setup``,
    ``settings``, ``result`` (an ``addon.gpu.result.RenderResult``), ``scene``
    and ``method``; nothing is kept here. Raises ``WarpError`` with a
    user-facing message.

    The frame, in order: the scene's geometry (cached: only what changed is
    read and uploaded), the view and light, the camera pre-pass (read back per
    tile: what the camera sees, ``addon.gpu.visibility``), B fitted to it and
    the warp (both kept while the geometry, view, light and settings are
    unchanged: :mod:`.warp_cache`), the depth pass, the shading pass, compose and one read-back of the
    images in ``read`` (default: the combined image and the shadow), all with
    numpy's OpenBLAS at one thread (``addon.gpu.blas``). ``timed``: wait for the
    GPU after every stage so each stage's time is its own (the engine's F12
    waits once, at the read-back). ``targets``: the render targets (default:
    the process-wide pool). ``camera``: the camera the render starts from (default ``scene.camera``; the engine
    passes its ``camera_override``, see ``render_camera``); ``eye``: (matrix, shift x) of one view of a multi-view
    render (``describe.eye_view``)."""
    from ..gpu.batches import shared_batches
    from ..gpu.pipeline import ShadowFrame
    from ..scene.describe import (NO_FACES, NoLightError, check_finite_geometry, check_visible_range, describe_scene,
                                  evaluated, eye_view, light_notes, pick_light, render_camera, shadow_off)
    from ..scene.geometry import shared_cache
    from ..scene.linking import light_links
    from ..scene.notes import scene_notes
    from ..scene.world import world_light, world_shading

    scene = depsgraph.scene.original if depsgraph.scene.is_evaluated else depsgraph.scene
    settings = settings or scene_settings(scene)
    read = ("combined", "shadow_mask") if read is None else read
    timings = {}
    t = time.perf_counter()
    cache = shared_cache()
    surfaces = getattr(depsgraph.view_layer, "use_solid", True)   # View Layer > Filter > Surfaces: none drawn when off
    geometry = cache.update(depsgraph, exclude=is_debug_object if surfaces else _everything)
    check_finite_geometry(geometry)
    shared_batches().prune(cache.meshes)
    timings["extraction"] = time.perf_counter() - t
    t = time.perf_counter()
    camera = render_camera(scene, camera)
    # The light object itself, not looked up by name: a linked light may share its name with a local one.
    try:
        light_obj, unlit = pick_light(scene, depsgraph, depsgraph.view_layer.objects.active), None
    except NoLightError as exc:   # every light hidden (an animation's frame, say): the world's light alone
        light_obj, unlit = None, exc
    view, light, bounds = describe_scene(scene, depsgraph, camera=camera, light=light_obj, instances=geometry.instances,
                                         need_receivers=False, need_light=light_obj is not None)
    if light is None:   # no direct light: the shading's ambient term alone, as Blender's engines light such a frame
        light = Light("SUN", direction=view.direction, energy=0.0, name="no light")
    check_visible_range(view, settings, camera.name, scene)
    if eye is not None:
        view = eye_view(view, camera, *eye, depsgraph=depsgraph)
    # The world as Cycles lights it, of the evaluated scene (an animation render's frame's, not the original's).
    world = world_light(depsgraph.scene_eval.world)
    seen = world_shading(depsgraph.scene_eval.world, world, depsgraph.view_layer)   # as Cycles sees it
    if warnings is not None:   # the sidebar shows the same notes (addon.ui.live)
        warnings += [f"Lixel: {note}" for note in scene_notes(scene, depsgraph, light_obj, camera, view, bounds,
                                                             geometry.instances, world)]
    timings["describe"] = time.perf_counter() - t
    links = light_links(light_obj, geometry.instances)   # Light/Shadow Linking: what it lights, what blocks it
    frame = ShadowFrame(geometry, view, resolution or view.resolution, read=read, targets=targets, timed=timed,
                        lit=links.lit, blocks=links.blocks)
    frame.camera_prepass()
    method = settings.method
    if method not in METHODS:
        if warnings is not None:
            warnings.append(f"Lixel method '{method}' is not available in this build; rendering with 'uniform'")
        method = "uniform"

    def warp():
        b, setup, seconds = fit_warp(frame, light, bounds, settings.warp, method)
        if seconds is not None:
            timings["visibility"] = seconds
        return b, setup

    t = time.perf_counter()
    try:
        if not surfaces:
            raise EmptyBodyError(f"view layer '{depsgraph.view_layer.name}' has Surfaces off (View Layer properties > "
                                 f"Filter), so as in Cycles the frame shows only the world background")
        if len(bounds.receivers) == 0:   # everything hidden (an animation's frame, say): the world, as Blender's engines
            raise EmptyBodyError(f"scene '{scene.name}' {NO_FACES}, so the frame shows only the world background")
        if unlit is not None:
            raise EmptyBodyError(f"{unlit}; the frame is lit by the world alone")
        if off := shadow_off(light_obj, depsgraph):   # as in Blender's engines: lit, unshadowed
            raise EmptyBodyError(off)
        # The pre-pass, hence the visible region, is a function of the geometry and the view.
        body, setup = shared_warps().get((geometry, bounds), (method, view, light, settings.warp, frame.size), warp)
    except EmptyBodyError as exc:
        # Nothing the camera sees can be shadowed (it looks at the sky, or no visible
        # surface is inside the spot cone): render the lighting without shadows.
        if warnings is not None:
            warnings.append(f"Lixel: no shadows in this view ({exc})")
        body = None
        setup = no_shadow_setup(method)
    timings["warp"] = time.perf_counter() - t - timings.get("visibility", 0.0)
    if warnings is not None:
        warnings.extend(light_notes(light_obj, depsgraph))
    light_data = evaluated(light_obj, depsgraph).data if light_obj is not None else None   # this frame's
    blend = float(light_data.spot_blend) if light_data is not None and light_data.type == "SPOT" else 0.0
    frame.draw_maps(setup, settings.shadow, body)
    frame.shade(light, setup, settings.shadow, spot_blend=blend, ambient=seen.ambient, background=seen.background,
                transparent=bool(scene.render.film_transparent))
    result = frame.finish()
    result.timings = {**timings, **result.timings}
    return {"setup": setup, "settings": settings, "result": result, "scene": scene.name, "method": method}


def _everything(ob) -> bool:
    """An ``exclude`` for ``GeometryCache.update`` that leaves every object out (a view layer without surfaces)."""
    return True


def result_window(render, w: int, h: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1), row 0 at the bottom, of the (w, h) frame that Blender's render result holds: the render
    border when one is on (Blender sizes the result to it, truncating ``border * size`` as its pipeline does; the
    frame is rendered whole and cut), else the whole frame."""
    if not render.use_border:
        return 0, 0, w, h
    return (int(render.border_min_x * w), int(render.border_min_y * h),
            int(render.border_max_x * w), int(render.border_max_y * h))


def _set_pass(layer, name: str, data: np.ndarray) -> None:
    rp = layer.passes.find_by_name(name, "") if hasattr(layer.passes, "find_by_name") else layer.passes.get(name)
    if rp is None:
        rp = layer.passes.get(name)
    if rp is None:
        log.warning("Lixel: render pass %s missing", name)
        return
    flat = np.ascontiguousarray(data, dtype=np.float32).reshape(-1)
    try:
        rp.rect.foreach_set(flat)
    except (AttributeError, TypeError):
        rp.rect = flat.reshape(len(flat) // rp.channels, rp.channels).tolist()


class LixelRenderEngine(bpy.types.RenderEngine):
    """Renders the camera's view with Lixel's warped shadow maps."""

    bl_idname = "LIXEL"
    bl_label = "Lixel"
    bl_use_gpu_context = True
    bl_use_preview = False

    def render(self, depsgraph):
        try:
            from ..gpu.context import ensure_gpu_context
            from ..scene.describe import render_views
            from .heap import keep_frame_buffers
            keep_frame_buffers()  # the passes' buffers of one F12 serve the next
            ensure_gpu_context()
            passes = enabled_passes(depsgraph.view_layer)
            read = frozenset({"combined"} | {row[5] for row in passes}).union(*(r for _, r in _watchers))
            views = render_views(depsgraph.scene) or [""]
        except Exception as exc:  # noqa: BLE001 - the entry point's guard: a message, never a traceback
            self.report({"ERROR"}, f"Lixel: {user_message(exc, f'rendering scene {depsgraph.scene.name!r}')}")
            return
        for name, channels, chan_id, *_ in passes:
            self.add_pass(name, channels, chan_id)
        reported: set = set()
        for view in views:   # Stereoscopy: each view (eye) with its own camera, as Cycles renders them
            if not self._render_view(depsgraph, view, passes, read, reported):
                return

    def _render_view(self, depsgraph, view: str, passes, read, reported: set) -> bool:
        """Render one view ("" without multi-view) into Blender's result; False (reported) when it cannot. A
        warning already in ``reported`` (an earlier view's) is not reported again."""
        try:
            if view:
                self.active_view_set(view)
            camera = self.camera_override   # (evaluated) this view's camera: the 3D view's Local Camera, or the scene's
            eye = None
            if view and camera is not None:
                eye = (np.array(self.camera_model_matrix(camera, use_spherical_stereo=False), dtype=np.float64),
                       float(self.camera_shift_x(camera, use_spherical_stereo=False)))
            warnings: list = []
            out = render_depsgraph(depsgraph, warnings=warnings, timed=False, read=read,
                                   camera=camera.original if camera is not None else None, eye=eye)
        except Exception as exc:  # noqa: BLE001 - the entry point's guard: a message, never a traceback
            what = f"rendering scene {depsgraph.scene.name!r}" + (f", view {view!r}" if view else "")
            self.report({"ERROR"}, f"Lixel: {user_message(exc, what)}")
            return False
        for msg in warnings:
            if msg not in reported:
                self.report({"WARNING"}, msg)
                reported.add(msg)
        for got, _ in _watchers:
            got.append({**out, "warnings": tuple(warnings), "view": view})
        res = out["result"]
        t = time.perf_counter()
        x0, y0, x1, y1 = result_window(depsgraph.scene.render, *res.resolution)
        # This view layer's part of the result (Blender calls render() once per view layer; "" is the first).
        result = self.begin_result(0, 0, x1 - x0, y1 - y0, layer=depsgraph.view_layer.name, view=view)
        layer = result.layers[0]
        _set_pass(layer, "Combined", res.combined[y0:y1, x0:x1])
        for name, *_, image in passes:
            _set_pass(layer, name, getattr(res, image)[y0:y1, x0:x1])
        self.end_result(result)
        res.timings["passes"] = time.perf_counter() - t
        c = res.counts
        self.update_stats("Lixel", f"{out['method']}: {c.maps} map(s), {c.casters_drawn} casters drawn "
                                   f"({c.caster_triangles_drawn} tris), {c.casters_culled} culled")
        return True

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name, channels, chan_id, kind, *_ in enabled_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)


def _panels():
    """Blender's property panels that should show for the Lixel engine too."""
    wanted = {"RENDER_PT_format", "RENDER_PT_frame_range", "RENDER_PT_output", "RENDER_PT_color_management",
              "DATA_PT_camera", "DATA_PT_lens", "DATA_PT_camera_display", "DATA_PT_light", "DATA_PT_context_light",
              "DATA_PT_context_camera", "OBJECT_PT_visibility"}
    for name in dir(bpy.types):
        if name in wanted:
            panel = getattr(bpy.types, name)
            if hasattr(panel, "COMPAT_ENGINES"):
                yield panel


classes = (LIXEL_PG_passes, LIXEL_PT_view_layer_passes, LixelRenderEngine)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.ViewLayer.lixel_passes = bpy.props.PointerProperty(type=LIXEL_PG_passes)
    for panel in _panels():
        panel.COMPAT_ENGINES.add(LixelRenderEngine.bl_idname)


def unregister():
    for panel in _panels():
        panel.COMPAT_ENGINES.discard(LixelRenderEngine.bl_idname)
    del bpy.types.ViewLayer.lixel_passes
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
