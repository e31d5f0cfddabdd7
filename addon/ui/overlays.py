"""Viewport overlays: draw handlers on ``SpaceView3D`` and the handlers that keep
the live state current.

* One ``POST_VIEW`` handler draws B (translucent faces and edges), the view and
  light frusta, the warp frustum P with its projection centre, V_P and B's middle
  vector, and the texel-grid checker / footprint heatmap on the receivers. One
  ``POST_PIXEL`` handler draws the shadow map picture-in-picture and the status
  line. They are added when the first overlay is switched on, removed when the
  last is switched off, on file load (``load_pre``) and on unregister.
* ``depsgraph_update_post`` classifies what changed (camera, light, other
  objects, settings) and calls :func:`live.update` with only that, then tags
  the 3D views for redraw; ``frame_change_post`` does the same for what a frame
  change animated (Blender announces a frame change with it alone), except an
  animation render's own frames.

What is drawn comes from :mod:`.overlay_geometry` (pure numpy, tested in
background mode); this module only uploads it. Shaders: the built-in
``UNIFORM_COLOR`` (named ``3D_UNIFORM_COLOR`` before Blender 4.0, tried as a
fallback) and, for the texel checker and heatmap, one shader made with
``GPUShaderCreateInfo`` (``GPUShader(vert, frag)`` is gone in 5.0).
"""
from __future__ import annotations

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ..gpu.batches import drawing_origin
from ..gpu.layout import Member, Struct
from ..gpu.pipeline import relative
from ..guard import guarded_callback, user_message
from . import live

_handles: dict[str, object] = {}
_batches: dict = {}
"""(scene key, overlay) -> (generation, GPU batches), rebuilt when the generation changes."""
_receivers: dict = {}
"""scene key -> (scene bounds, triangles (T,3,3), GPU batch or None) of the receivers for the texel/heatmap overlays."""

COLOURS = {
    "body_face": (1.0, 0.55, 0.1),
    "body_edge": (1.0, 0.55, 0.1, 0.9),
    "view": (0.3, 0.8, 1.0, 0.9),
    "light": (1.0, 0.95, 0.3, 0.9),
    "warp": (1.0, 0.3, 0.9, 0.9),
    "v_p": (0.2, 1.0, 0.3, 1.0),
    "middle_vector": (0.1, 0.6, 1.0, 1.0),
    "point": (1.0, 1.0, 1.0, 1.0),
}
SPLIT_COLOURS = ((1.0, 0.3, 0.3, 0.95), (0.3, 1.0, 0.4, 0.95), (0.35, 0.55, 1.0, 0.95), (1.0, 0.85, 0.2, 0.95),
                 (0.85, 0.35, 1.0, 0.95), (0.2, 0.95, 0.95, 0.95), (1.0, 0.55, 0.15, 0.95), (0.8, 0.8, 0.8, 0.95))
"""A cascade's splits, nearest first (at most 8): each split's B, maps and slab of the view in its own colour."""
COLOURS.update({f"split{i}": c for i, c in enumerate(SPLIT_COLOURS)})

GPU_OVERLAYS = ("show_map", "show_shadowed")
PIP_BOTTOM = 60
"""Pixels between the region's bottom and the picture-in-picture images (room for the status line)."""
"""Overlays that need the gpu pipeline (``addon/gpu``)."""


# --- shaders -------------------------------------------------------------------------------------------------

def builtin_shader(*names):
    """The first built-in shader of ``names`` this Blender has (names changed in 4.0/5.0)."""
    import gpu
    last = None
    for n in names:
        try:
            return gpu.shader.from_builtin(n)
        except (ValueError, KeyError, TypeError) as exc:
            last = exc
    raise RuntimeError(f"none of the built-in shaders {names} exists: {last}")


def uniform_colour_shader():
    return builtin_shader("UNIFORM_COLOR", "3D_UNIFORM_COLOR")


def point_shader():
    """Points (``POINT_UNIFORM_COLOR`` since 4.5; drawing points with ``UNIFORM_COLOR`` is deprecated in 5.0)."""
    return builtin_shader("POINT_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR")


def line_shader():
    """Wide lines (uniforms ``viewportSize``, ``lineWidth``, ``color``)."""
    return builtin_shader("POLYLINE_UNIFORM_COLOR", "3D_POLYLINE_UNIFORM_COLOR")


_TEXEL_SHADER = None

TEXEL_VERTEX = """
void main()
{
  v_world = pos;
  gl_Position = u_view_projection * vec4(pos, 1.0);
}
"""

TEXEL_FRAGMENT = """
/* The first map whose clip volume holds the point (docs/architecture.md, map selection),
   its texel coordinate with the explicit homogeneous divide, then either the parity checker
   of the texel grid or the footprint: the side of one texel in screen pixels, from the screen
   derivatives of the texel coordinate (Stamminger-Drettakis §1.1). */
void main()
{
  int found = -1;
  vec2 texel = vec2(0.0);
  for (int i = 0; i < u_count; i++) {
    vec4 c = u_maps.light[i] * vec4(v_world, 1.0);
    if (c.w <= 0.0) continue;
    vec3 ndc = c.xyz / c.w;
    if (any(greaterThan(abs(ndc), vec3(1.0)))) continue;
    found = i;
    texel = (ndc.xy * 0.5 + 0.5) * u_size;
    break;
  }
  if (found < 0) {
    FragColor = vec4(NO_MAP, 0.25 * u_alpha);
    return;
  }
  if (u_mode == 0) {
    ivec2 t = ivec2(floor(texel));
    float parity = float((t.x + t.y) & 1);
    vec3 a = (found % 2 == 0) ? TEXEL_EVEN_MAP : TEXEL_ODD_MAP;
    FragColor = vec4(mix(a, TEXEL_DARK, parity), u_alpha);
  } else {
    /* A = d texel / d pixel (columns dFdx, dFdy); the footprint (addon.measure.footprint) is the largest
       singular value of A^-1 = 1 / the smallest singular value of A: screen pixels one texel spans. */
    vec2 ax = dFdx(texel), ay = dFdy(texel);
    float t = dot(ax, ax) + dot(ay, ay);
    float d = ax.x * ay.y - ax.y * ay.x;
    float s_min = sqrt(max(0.5 * (t - sqrt(max(t * t - 4.0 * d * d, 0.0))), 0.0));
    float px = 1.0 / max(s_min, 1e-6);
    float s = clamp(log2(px) / (2.0 * HEAT_LOG2_RANGE) + 0.5, 0.0, 1.0);
    vec3 col = s < 0.5 ? mix(HEAT_LOW, HEAT_MID, s * 2.0) : mix(HEAT_MID, HEAT_HIGH, s * 2.0 - 1.0);
    FragColor = vec4(col, u_alpha);
  }
}
"""

MAX_SHADER_MAPS = 6
"""The checker/heatmap shader serves up to this many maps (a point light's cube faces)."""
OVERLAY_MAPS = Struct("LixelOverlayMaps", (
    Member("light", "mat4", "world -> light clip of each map, in selection order", MAX_SHADER_MAPS),),
    doc="The checker/heatmap shader's maps: a uniform block (push constants hold at most 128 bytes).")

HEATMAP_LOG2_RANGE = 2.0
"""The footprint heatmap spans log2(screen pixels per texel) from -this to +this."""
HEATMAP_COLOURS = ((0.1, 0.2, 1.0), (0.1, 0.9, 0.2), (1.0, 0.1, 0.1))
"""Heatmap colours at -range (texels much smaller than pixels), 0 (one pixel per texel) and +range (blocky)."""
TEXEL_COLOURS = {"even map": (0.95, 0.95, 0.95), "odd map": (0.95, 0.85, 0.6), "dark": (0.1, 0.1, 0.15),
                 "no map": (0.5, 0.5, 0.5)}
"""Texel checker: light squares of maps 0, 2, 4 / 1, 3, 5, the dark squares, and receivers no map serves."""
RECEIVER_ALPHA = 0.85
"""Opacity of the checker and heatmap over the scene."""


def _vec3(c) -> str:
    return "vec3({:.6g}, {:.6g}, {:.6g})".format(*c)


def texel_shader_defines() -> dict:
    """The texel/heatmap shader's colour constants, from the Python ones above (one place for the legend and GLSL)."""
    return {"HEAT_LOG2_RANGE": f"{HEATMAP_LOG2_RANGE:.6g}", "HEAT_LOW": _vec3(HEATMAP_COLOURS[0]),
            "HEAT_MID": _vec3(HEATMAP_COLOURS[1]), "HEAT_HIGH": _vec3(HEATMAP_COLOURS[2]),
            "TEXEL_EVEN_MAP": _vec3(TEXEL_COLOURS["even map"]), "TEXEL_ODD_MAP": _vec3(TEXEL_COLOURS["odd map"]),
            "TEXEL_DARK": _vec3(TEXEL_COLOURS["dark"]), "NO_MAP": _vec3(TEXEL_COLOURS["no map"])}


def texel_shader():
    """The texel-checker / footprint-heatmap shader (built once, needs a GPU context)."""
    global _TEXEL_SHADER
    if _TEXEL_SHADER is None:
        import gpu
        iface = gpu.types.GPUStageInterfaceInfo("lixel_texel_iface")
        iface.smooth("VEC3", "v_world")
        info = gpu.types.GPUShaderCreateInfo()
        info.vertex_in(0, "VEC3", "pos")
        info.vertex_out(iface)
        info.push_constant("MAT4", "u_view_projection")
        info.typedef_source(OVERLAY_MAPS.glsl())
        info.uniform_buf(0, OVERLAY_MAPS.name, "u_maps")
        info.push_constant("VEC2", "u_size")
        info.push_constant("INT", "u_count")
        info.push_constant("INT", "u_mode")
        info.push_constant("FLOAT", "u_alpha")
        info.fragment_out(0, "VEC4", "FragColor")
        for name, value in texel_shader_defines().items():
            info.define(name, value)
        info.vertex_source(TEXEL_VERTEX)
        info.fragment_source(TEXEL_FRAGMENT)
        _TEXEL_SHADER = gpu.shader.create_from_info(info)
    return _TEXEL_SHADER


# --- handler management --------------------------------------------------------------------------------------

def wanted(scene) -> bool:
    props = getattr(scene, "lixel", None)
    return props is not None and props.any_overlay()


def sync_handlers(context=None) -> None:
    """Add the draw handlers if any scene shows an overlay, remove them otherwise,
    and tag the 3D views for redraw."""
    scenes = bpy.data.scenes if hasattr(bpy.data, "scenes") else ()
    need = any(wanted(s) for s in scenes)
    if need:
        add_draw_handlers()
    else:
        remove_draw_handlers()
    tag_redraw(context)


def add_draw_handlers() -> None:
    if "view" not in _handles:
        _handles["view"] = bpy.types.SpaceView3D.draw_handler_add(draw_view, (), "WINDOW", "POST_VIEW")
    if "pixel" not in _handles:
        _handles["pixel"] = bpy.types.SpaceView3D.draw_handler_add(draw_pixel, (), "WINDOW", "POST_PIXEL")


def remove_draw_handlers() -> None:
    for key in ("view", "pixel"):
        h = _handles.pop(key, None)
        if h is not None:
            bpy.types.SpaceView3D.draw_handler_remove(h, "WINDOW")
    _batches.clear()
    _receivers.clear()
    _pip.clear()


def draw_handlers_active() -> tuple[str, ...]:
    return tuple(sorted(_handles))


def tag_redraw(context=None) -> None:
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


# --- live updates ----------------------------------------------------------------------------------------------

def classify_updates(scene, depsgraph) -> set:
    """Which live inputs a depsgraph update touched: 'view' (the scene camera or
    its data), 'light' (any light: the chosen one may change), 'bounds' (any
    other object or geometry), 'settings' (the scene itself)."""
    changed = set()
    cam = live.followed_camera(scene)
    cam_data = cam.data if cam is not None else None
    for u in depsgraph.updates:
        idb = u.id
        orig = getattr(idb, "original", idb)
        if isinstance(orig, bpy.types.Scene):
            changed.add("settings")
            changed.add("view")   # the scene camera or the render size may have changed
            changed.add("light")  # an object added or deleted (the light itself) changes which light Lixel uses
        elif isinstance(orig, bpy.types.Object):
            if cam is not None and orig == cam:
                changed.add("view")
            elif orig.type == "LIGHT":
                changed.add("light")
            elif orig.type == "CAMERA":
                continue
            else:
                changed.add("bounds")
        elif isinstance(orig, bpy.types.Camera):
            if cam_data is not None and orig == cam_data:
                changed.add("view")
        elif isinstance(orig, bpy.types.Light):
            changed.add("light")
        elif isinstance(orig, (bpy.types.Mesh, bpy.types.Curve, bpy.types.MetaBall, bpy.types.NodeTree,
                               bpy.types.Collection)):
            changed.add("bounds")
    return changed


def forget_deleted_scenes() -> None:
    """Drop the GPU batches and pictures of scenes that no longer exist."""
    if not (_batches or _receivers or _pip):
        return
    alive = live.living_scene_keys()
    for cache in (_batches, _receivers, _pip):
        for k in [k for k in cache if (k[0] if isinstance(k, tuple) else k) not in alive]:
            del cache[k]


@persistent
@guarded_callback("updating Lixel after a scene change")
def on_depsgraph_update(scene, depsgraph):
    """Recompute only what changed, for scenes Lixel already computed and that
    have live updates on (the cost goes to the panel's timing readout)."""
    forget_deleted_scenes()
    props = getattr(scene, "lixel", None)
    if props is None or not props.live_update or live.state(scene) is None:
        return
    changed = classify_updates(scene, depsgraph)
    if not changed:
        return
    try:
        active = depsgraph.view_layer.objects.active
    except (AttributeError, ReferenceError):
        active = None
    st = live.update(scene, depsgraph, changed=changed, active=active, moving=True)
    if st.provisional:      # a cascade with the λ splits: the adaptive ones once the view rests
        live.refine_when_resting(tag_redraw)
    tag_redraw()


@persistent
@guarded_callback("updating Lixel after a frame change")
def on_frame_change(scene, depsgraph=None):
    """The timeline moved (scrubbing, playback, ``frame_set``): what the frame animated is in ``depsgraph.updates``,
    and no ``depsgraph_update_post`` follows. An animation render's frames (a RENDER depsgraph) are not the
    viewport's and leave its state alone."""
    if depsgraph is not None and depsgraph.mode == "VIEWPORT":
        on_depsgraph_update(scene, depsgraph)


@persistent
@guarded_callback("clearing Lixel's state before a file load")
def on_load_pre(*_args):
    """A file is being loaded: drop the draw handlers, batches and live state
    (they point at the old file's data)."""
    remove_draw_handlers()
    live.clear()


@persistent
@guarded_callback("setting up Lixel's overlays after a file load")
def on_load_post(*_args):
    """Re-add the draw handlers if the loaded file has overlays switched on.
    Nothing is written into the file's scenes: one never set up renders with the
    preference defaults (``LixelSceneSettings.to_settings``) until the user
    changes a setting or runs an operator."""
    sync_handlers()


APP_HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("frame_change_post", on_frame_change),
                ("load_pre", on_load_pre), ("load_post", on_load_post))


# --- drawing ---------------------------------------------------------------------------------------------------

def _scene_state():
    scene = bpy.context.scene
    if scene is None or not wanted(scene):
        return None, None
    st = live.state(scene)
    moved = live.follow(scene, live.local_camera(bpy.context))     # this view's Local Camera, as its F12 renders
    if st is None or moved:
        st = live.update(scene, bpy.context.evaluated_depsgraph_get(), changed=None if st is None else {"view"},
                         active=bpy.context.view_layer.objects.active)
    return scene, st


def _line_batch(shader, segments):
    from gpu_extras.batch import batch_for_shader
    pos = np.asarray(segments, dtype=np.float32).reshape(-1, 3)
    return batch_for_shader(shader, "LINES", {"pos": pos})


def _tri_batch(shader, triangles):
    from gpu_extras.batch import batch_for_shader
    pos = np.asarray(triangles, dtype=np.float32).reshape(-1, 3)
    return batch_for_shader(shader, "TRIS", {"pos": pos})


def _point_batch(shader, points):
    from gpu_extras.batch import batch_for_shader
    pos = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    return batch_for_shader(shader, "POINTS", {"pos": pos})


def _cached(scene_key, key, generation, build):
    k = (scene_key, key)
    hit = _batches.get(k)
    if hit is not None and hit[0] == generation:
        return hit[1]
    value = build()
    _batches[k] = (generation, value)
    return value


def line_sets(props, geometry) -> list:
    """(name, colour key, (E, 2, 3) segments) to draw for the enabled line overlays."""
    out = []
    if props.show_body:
        out.append(("body_edges", "body_edge", geometry["body_edges"]))
    if props.show_frusta:
        out.append(("view_lines", "view", geometry["view_lines"]))
        out.append(("light_lines", "light", geometry["light_lines"]))
    for i, split in enumerate(geometry.get("splits", [])):
        colour = f"split{i % len(SPLIT_COLOURS)}"
        if props.show_body:
            out.append((f"split{i}_body", colour, split["body_edges"]))
        if props.show_frusta:
            out.append((f"split{i}_view", colour, split["view_lines"]))
            out.append((f"split{i}_light", colour, split["light_lines"]))
    if props.show_warp:
        out.append(("warp_lines", "warp", geometry["warp_lines"]))
        for name, seg in geometry["vectors"].items():
            out.append((f"vector_{name}", name, seg[None]))
    return [(n, c, s) for n, c, s in out if len(s)]


@guarded_callback("drawing Lixel's viewport overlays")
def draw_view():
    """POST_VIEW: B, the frusta, P and its vectors, texels/heatmap on receivers."""
    scene, st = _scene_state()
    if st is None or st.geometry is None:
        return
    region_data = bpy.context.region_data
    if region_data is None:
        return
    draw_scene_overlays(scene, st, scene.lixel, np.array(region_data.perspective_matrix, dtype=np.float64))


def draw_scene_overlays(scene, st, props, view_projection) -> None:
    """Draw the 3D overlays of ``st`` seen through ``view_projection`` (world ->
    clip) into the bound framebuffer: the viewport's POST_VIEW handler and the
    off-screen snapshots (:mod:`.snapshot`) both call this. ``props``: the
    scene's Lixel properties or anything with the same ``show_*`` and
    ``body_alpha`` attributes. The GPU matrices are set from ``view_projection``
    for the duration (in the viewport it equals the region's perspective matrix)."""
    import gpu
    import mathutils
    with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
        gpu.matrix.load_identity()
        gpu.matrix.load_projection_matrix(mathutils.Matrix(np.asarray(view_projection, dtype=np.float64).tolist()))
        _draw_scene_overlays(scene, st, props, view_projection)


def _draw_scene_overlays(scene, st, props, view_projection) -> None:
    import gpu
    geometry = st.geometry
    shader = uniform_colour_shader()
    gpu.state.blend_set("ALPHA")
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.depth_mask_set(False)
    try:
        if props.show_texels or props.show_footprint:
            _draw_receivers(scene, st, props, view_projection)
        shader.bind()
        if props.show_body and len(geometry["body_triangles"]):
            batch = _cached(live.scene_key(scene), "body_triangles", st.generation,
                            lambda: _tri_batch(shader, geometry["body_triangles"]))
            shader.uniform_float("color", (*COLOURS["body_face"], props.body_alpha))
            batch.draw(shader)
        lines = line_shader()
        lines.bind()
        lines.uniform_float("viewportSize", tuple(float(v) for v in gpu.state.viewport_get()[2:]))
        lines.uniform_float("lineWidth", 2.0)
        for name, colour, segments in line_sets(props, geometry):
            batch = _cached(live.scene_key(scene), name, st.generation, lambda s=segments: _line_batch(lines, s))
            lines.uniform_float("color", COLOURS[colour])
            batch.draw(lines)
        if props.show_warp and geometry["points"]:
            points = point_shader()
            points.bind()
            gpu.state.point_size_set(8.0)
            pts = np.array(list(geometry["points"].values()))
            batch = _cached(live.scene_key(scene), "points", st.generation, lambda: _point_batch(points, pts))
            points.uniform_float("color", COLOURS["point"])
            batch.draw(points)
            gpu.state.point_size_set(1.0)
    finally:
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")


def receiver_triangles(depsgraph) -> np.ndarray:
    """(T, 3, 3) world-space triangles of every drawable instance except Lixel's
    debug objects (for the receiver overlays), from the scene cache the render
    engine and the live state use (:func:`live.scene_geometry`)."""
    geometry = live.scene_geometry(depsgraph)
    inst = geometry.instances
    out = []
    for k, key in enumerate(inst.key_list):
        mats = inst.matrices[inst.key_ids == k]
        if not len(mats):
            continue
        mesh = geometry.meshes[key]
        local = np.asarray(mesh.positions, dtype=np.float64)[mesh.triangles].reshape(-1, 3)
        world = np.einsum("nij,vj->nvi", mats[:, :3, :3], local) + mats[:, None, :3, 3]
        out.append(world.reshape(-1, 3, 3))
    return np.concatenate(out) if out else np.zeros((0, 3, 3))


def receiver_triangles_of(scene, st) -> np.ndarray:
    """The receiver triangles of ``scene`` (world, (T, 3, 3)), read again only
    when the state's scene bounds changed."""
    hit = _receivers.get(live.scene_key(scene))
    if hit is None or hit[0] is not st.bounds:
        tris = receiver_triangles(bpy.context.evaluated_depsgraph_get())
        _receivers[live.scene_key(scene)] = hit = (st.bounds, tris, None)
    return hit[1]


def triangles_origin(triangles: np.ndarray) -> np.ndarray:
    """The point the receiver overlays (and the snapshot's backdrop) draw (T, 3, 3) world ``triangles`` relative to."""
    return drawing_origin(np.stack([triangles.min(axis=1), triangles.max(axis=1)], axis=1))


def _maps_block(maps, origin):
    """The maps' matrices, for coordinates relative to ``origin``, as the shader's uniform block
    (:data:`OVERLAY_MAPS`)."""
    import gpu
    block = OVERLAY_MAPS.block()
    for i, m in enumerate(maps):
        block.light[i][:] = relative(m.matrix, origin).T  # a row per column (GLSL is column-major)
    return gpu.types.GPUUniformBuf(block.float32().tobytes())


def _draw_receivers(scene, st, props, view_projection):
    """The texel-parity checker and/or footprint heatmap on every receiver, with
    the receiver shader (per-fragment map selection and divide). The receivers
    are drawn relative to their drawing origin (``batches.drawing_origin``), as
    the render draws the scene: in world coordinates float32 steps 6 cm at
    1000 km, which turned the heatmap's screen derivatives to noise."""
    import mathutils
    from gpu_extras.batch import batch_for_shader
    shader = texel_shader()
    tris = receiver_triangles_of(scene, st)
    if not len(tris):
        return
    bounds, _, drawn = _receivers[live.scene_key(scene)]
    if drawn is None:
        origin = triangles_origin(tris)
        drawn = (batch_for_shader(shader, "TRIS", {"pos": (tris - origin).reshape(-1, 3).astype(np.float32)}), origin)
        _receivers[live.scene_key(scene)] = (bounds, tris, drawn)
    batch, origin = drawn
    maps = st.setup.maps[:MAX_SHADER_MAPS]
    shader.bind()
    shader.uniform_float("u_view_projection", mathutils.Matrix(relative(view_projection, origin).tolist()))
    shader.uniform_block("u_maps", _cached(live.scene_key(scene), "maps", (st.generation, origin.tobytes()),
                                           lambda: _maps_block(maps, origin)))
    shader.uniform_float("u_size", tuple(float(v) for v in maps[0].size))
    shader.uniform_int("u_count", len(maps))
    shader.uniform_float("u_alpha", RECEIVER_ALPHA)
    for mode, on in ((0, props.show_texels), (1, props.show_footprint)):
        if on:
            shader.uniform_int("u_mode", mode)
            batch.draw(shader)


@guarded_callback("drawing Lixel's viewport status and pictures")
def draw_pixel():
    """POST_PIXEL: status line and the shadow map picture-in-picture."""
    scene, st = _scene_state()
    if st is None:
        return
    import blf
    props = scene.lixel
    font = 0
    blf.size(font, 13)
    blf.color(font, 1.0, 1.0, 1.0, 0.9)
    y = 40
    text = (f"Lixel: {st.error}" if st.error else
            f"Lixel {st.method_used}: {len(st.setup.maps)} map(s), B {len(st.setup.diagnostics.body_vertices)} "
            f"vertices, update {st.total_ms():.1f} ms")
    blf.position(font, 20, y, 0)
    blf.draw(font, text)
    if (props.show_map or props.show_shadowed) and st.setup is not None:
        note = _draw_gpu_overlays(scene, st, props)
        if note:
            blf.position(font, 20, y + 18, 0)
            blf.draw(font, note)


def gpu_pipeline():
    """The gpu pipeline's module (``addon.gpu.pipeline``) if it is built, else None."""
    try:
        from ..gpu import pipeline
    except ImportError:
        return None
    return pipeline if hasattr(pipeline, "render_shadows") else None


_pip: dict = {}
"""scene key -> (key, {"map"|"scene": GPUTexture} or the error that rendering them raised, its TargetPool) for the
picture-in-picture overlays."""


def _pip_textures(scene, st, props) -> dict:
    """GPU textures of the PiP images, re-rendered only when the setup (generation)
    or what is shown changed; so is a render that failed (a refused map size is not
    tried again on every redraw of the viewport: its error is raised again)."""
    from ..gpu.targets import TargetPool
    from . import renders
    key = (st.generation, props.map_pip_size, props.show_map, props.show_shadowed)
    hit = _pip.get(live.scene_key(scene))
    if hit is not None and hit[0] == key:
        if isinstance(hit[1], Exception):
            raise hit[1]
        return hit[1]
    pool = hit[2] if hit is not None else TargetPool()   # the scene's own targets: no other frame draws over them
    try:
        textures = renders.pip_textures(st, bpy.context.evaluated_depsgraph_get(), props.map_pip_size,
                                        props.show_map, props.show_shadowed, pool)
    except Exception as exc:
        _pip[live.scene_key(scene)] = (key, exc, pool)
        raise
    _pip[live.scene_key(scene)] = (key, textures, pool)
    return textures


def _draw_texture(texture, x, y, w, h):
    from gpu_extras.batch import batch_for_shader
    shader = builtin_shader("IMAGE", "2D_IMAGE")
    batch = batch_for_shader(shader, "TRI_STRIP", {"pos": ((x, y), (x + w, y), (x, y + h), (x + w, y + h)),
                                                   "texCoord": ((0, 0), (1, 0), (0, 1), (1, 1))})
    shader.bind()
    shader.uniform_sampler("image", texture)
    batch.draw(shader)


def _draw_gpu_overlays(scene, st, props) -> str:
    """The shadow map and the shadowed camera view, picture-in-picture at the
    bottom right. Returns a note for the status line when they cannot be drawn."""
    if gpu_pipeline() is None:
        return "shadow map / shadowed scene overlays need the gpu pipeline (addon/gpu), not available"
    try:
        textures = _pip_textures(scene, st, props)
    except Exception as exc:  # noqa: BLE001 - shown in the status line instead of the pictures
        return f"Lixel render: {user_message(exc, f'rendering the pictures of scene {scene.name!r}')}"
    import gpu
    region = bpy.context.region
    x = (region.width if region is not None else gpu.state.viewport_get()[2]) - 20
    for name in ("scene", "map"):
        tex = textures.get(name)
        if tex is None:
            continue
        x -= tex.width
        _draw_texture(tex, x, PIP_BOTTOM, tex.width, tex.height)
        x -= 10
    return ""


def register():
    for name, fn in APP_HANDLERS:
        getattr(bpy.app.handlers, name).append(fn)
    sync_handlers()   # enabled again (Preferences) over a file whose overlays are on (at start-up: on_load_post)


def unregister():
    for name, fn in APP_HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        while fn in lst:
            lst.remove(fn)
    remove_draw_handlers()
    live.clear()
    global _TEXEL_SHADER
    _TEXEL_SHADER = None
