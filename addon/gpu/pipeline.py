"""The gpu pipeline: shadow maps drawn with Blender's ``gpu`` module and the
camera's view shaded with them. :func:`render_shadows` is the public entry
point (render engine, report, UI); see docs/architecture.md.

Stages (each timed): upload (batches for new/changed meshes and instance
tables), depth pass (one DEPTH_COMPONENT32F texture per map), MDSM build
(n > 1), shading (camera depth pre-pass, then the shading pass with
LESS_EQUAL), read-back, compose (eye-space blur, combined image, heatmap).
"""
from __future__ import annotations

import logging
import math
import time
from typing import Optional

import numpy as np

from ..settings import LixelSettings, ShadowSettings
from ..warp.body import intersection_body
from ..warp.culling import boxes_meeting
from ..warp.geometry import perpendicular, translation
from ..warp.polyhedron import face_planes, hexahedron_faces
from ..warp.types import EmptyBodyError, Light, SceneBounds, ShadowSetup, View, WarpError
from . import shaders
from .batches import BatchCache, draw_table, instance_table, shared_batches

log = logging.getLogger(__name__)

DEFAULT_ALBEDO = 0.8
"""Grey of every surface (Blender's default material base colour)."""
DEFAULT_AMBIENT = (0.05, 0.05, 0.05)
"""World colour when none is given (Blender's default world)."""


def _sync(fb, color: bool = False) -> None:
    """Wait for the GPU (no gpu.finish in the API: read one pixel). Mesa's
    llvmpipe finishes only what the read depends on: read colour after a pass
    that writes colour but not depth."""
    with fb.bind():
        if color:
            fb.read_color(0, 0, 1, 1, 4, 0, "FLOAT")
        else:
            fb.read_depth(0, 0, 1, 1)


def _buffer(array: np.ndarray):
    import gpu
    return gpu.types.Buffer("FLOAT", array.shape, array)


SLOPE_LIMIT = 0.02
"""Largest slope term per texel (NDC depth units, 1% of the depth range), like
a depth-bias clamp: a surface nearly edge-on to the light has an unbounded
polygon-offset slope, and without a clamp its bias reaches past its own
occluders (light leaks behind casters on grazing receivers). A plane tilted 80°
from the light needs about 0.006 at 2048²."""


def bias_vector(shadow: ShadowSettings) -> tuple[float, float, float, float]:
    """The shading pass's bias uniform (Scherzer §4.2), NDC depth units:
    (constant c, slope factor s, PCF reach r = max(1, k/2), slope limit);
    see gpu_shaders/shade_frag.glsl."""
    mode = shadow.bias_mode
    c = shadow.constant_bias if mode in ("CONSTANT", "CONSTANT_SLOPE") else 0.0
    s = shadow.slope_bias if mode in ("SLOPE", "CONSTANT_SLOPE") else 0.0
    return float(c), float(s), max(1.0, shadow.pcf_kernel / 2.0), SLOPE_LIMIT


def relative(matrix: np.ndarray, origin) -> np.ndarray:
    """A world -> clip matrix for coordinates relative to ``origin``
    (``M @ translation(origin)``). The GPU works in float32 around the camera,
    so scenes far from the world origin keep their precision."""
    return np.asarray(matrix, dtype=np.float64) @ translation(origin)


def relative_row(row, origin) -> np.ndarray:
    """A depth row (r . [p, 1]) for coordinates relative to ``origin``."""
    r = np.asarray(row, dtype=np.float64).copy()
    r[3] += float(r[:3] @ np.asarray(origin, dtype=np.float64))
    return r


def light_facing_winds_clockwise(shadow_map) -> bool:
    """Whether a triangle facing the map's centre of projection (the light)
    winds clockwise in the map's window coordinates.

    OpenGL calls counter-clockwise triangles front-facing; Blender meshes wind
    counter-clockwise seen from outside. For a camera-like matrix a triangle
    facing the light is counter-clockwise, but a map may mirror x or y, and the
    determinant alone cannot tell (a GREATER map flips z as well), so a small
    triangle facing the light is projected and its signed area checked.
    """
    m = np.asarray(shadow_map.matrix, dtype=np.float64)
    try:
        inv = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        return False  # a degenerate map draws nothing: no winding to speak of

    def unproject(ndc):
        h = inv @ np.append(ndc, 1.0)
        return h[:3] / h[3]

    def project(p):
        h = m @ np.append(p, 1.0)
        return h[:2] / h[3]

    near, far = unproject((0.0, 0.0, -0.5)), unproject((0.0, 0.0, 0.5))
    away = far - near if shadow_map.depth_test != "GREATER" else near - far
    size = float(np.linalg.norm(away))
    n = -away / size  # towards the light
    u = perpendicular(n)
    v = np.cross(n, u)  # u x v = n
    a = project(near)
    b, c = project(near + u * size * 1e-3), project(near + v * size * 1e-3)
    area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return bool(area < 0)


def depth_pass(setup: ShadowSetup, geometry, table, shadow: ShadowSettings, batches: BatchCache,
               bare: bool = False, origin=(0.0, 0.0, 0.0)) -> list:
    """Draw every map of ``setup``: returns [(depth texture, framebuffer)].

    Per map: clear to 1 (LESS) or 0 (GREATER, reversed test), depth test
    LESS_EQUAL / GREATER_EQUAL with the depth mask on; back-face rendering
    culls the faces that face the light (Scherzer §4.2); linear z writes
    ``depth_row . [P, 1]`` per fragment. Constant and slope-scale bias are
    applied where depths are compared (shading pass), so otherwise this is a
    bare draw. ``bare`` (the benchmark's reference) also drops culling and
    linear z. ``origin``: the table's matrices are relative to it (see :func:`relative`).
    """
    import gpu
    out = []
    for m in setup.maps:
        w, h = (int(v) for v in m.size)
        tex = gpu.types.GPUTexture((w, h), format="DEPTH_COMPONENT32F")
        fb = gpu.types.GPUFrameBuffer(depth_slot=tex)
        greater = m.depth_test == "GREATER"
        linear = m.depth_row is not None and not bare
        shader = shaders.depth_shader(linear)
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            fb.clear(depth=0.0 if greater else 1.0)
            gpu.state.depth_test_set("GREATER_EQUAL" if greater else "LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            shader.bind()
            shader.uniform_float("u_light", _gl_matrix(relative(m.matrix, origin)))
            if linear:
                shader.uniform_float("u_depth_row", tuple(float(v) for v in relative_row(m.depth_row, origin)))
            cull = "FRONT" if (shadow.back_faces and not bare) else "NONE"
            draw_table(shader, batches, geometry, table, cull=cull, flip=light_facing_winds_clockwise(m))
            gpu.state.depth_mask_set(False)
            gpu.state.depth_test_set("NONE")
        out.append((tex, fb))
    return out


def _gl_matrix(m: np.ndarray):
    from mathutils import Matrix
    return Matrix(np.asarray(m, dtype=np.float64).tolist())


_fullscreen = None


def _fullscreen_batch():
    global _fullscreen
    if _fullscreen is None:
        from .batches import make_batch
        _fullscreen = make_batch(np.array([(-1, -1, 0), (3, -1, 0), (-1, 3, 0)], np.float32),
                                 np.array([(0, 1, 2)], np.int32))
    return _fullscreen


def mdsm_pass(maps: list, setup: ShadowSetup, shadow: ShadowSettings) -> list:
    """n-depth key maps (RGBA32F) from the depth maps (Pagot et al. §4.3)."""
    import gpu
    shader = shaders.mdsm_shader()
    out = []
    for (depth, _), m in zip(maps, setup.maps):
        w, h = (int(v) for v in m.size)
        keys = gpu.types.GPUTexture((w, h), format="RGBA32F")
        fb = gpu.types.GPUFrameBuffer(color_slots=(keys,))
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            gpu.state.depth_test_set("NONE")
            shader.bind()
            shader.uniform_sampler("u_depth", depth)
            shader.uniform_float("u_params", (float(shadow.mdsm_depths), float(shadow.mdsm_neighbourhood),
                                              1.0 if shadow.mdsm_selection == "SORT" else 0.0,
                                              1.0 if m.depth_test == "GREATER" else 0.0))
            _fullscreen_batch().draw(shader)
        out.append((keys, fb))
    return out


def shade_block(view: View, light: Light, setup: ShadowSetup, shadow: ShadowSettings,
                albedo: float = DEFAULT_ALBEDO, origin=(0.0, 0.0, 0.0), spot_blend: float = 0.0) -> np.ndarray:
    """The shading pass's std140 uniform block (see gpu_shaders/lixel_types.glsl),
    positions relative to ``origin``."""
    o = np.asarray(origin, dtype=np.float64)
    per_map = 4 + 5 + shaders.MAX_POLYGON
    header = 8
    block = np.zeros((header + shaders.MAX_MAPS * per_map, 4), dtype=np.float64)
    block[0] = (*(view.position - o), 1.0 if view.orthographic else 0.0)
    block[1, :3] = view.direction
    block[2] = relative_row(view.world_to_camera[2], o)
    kind = {"SUN": 0.0, "POINT": 1.0, "SPOT": 2.0}[light.type]
    block[3] = (*((light.position - o) if light.position is not None else (0, 0, 0)), kind)
    cos_half = math.cos(light.spot_angle / 2) if light.type == "SPOT" else -1.0
    block[4] = (*(light.direction if light.direction is not None else (0, 0, -1)), cos_half)
    block[5] = (*(np.asarray(light.color, dtype=np.float64) * light.energy), albedo)
    block[6] = (shadow.pcf_kernel, shadow.mdsm_depths, len(setup.maps), min(max(float(spot_blend), 0.0), 1.0))
    block[7] = bias_vector(shadow)
    for i, m in enumerate(setup.maps):
        base = header + i * per_map
        block[base:base + 4] = relative(m.matrix, o).T  # columns
        if m.depth_row is not None:
            block[base + 4] = relative_row(m.depth_row, o)
        block[base + 5] = (m.size[0], m.size[1], 1.0 if m.depth_test == "GREATER" else 0.0,
                           1.0 if m.depth_row is not None else 0.0)
        if m.view_depth_range is not None:
            block[base + 6, :3] = (m.view_depth_range[0], m.view_depth_range[1], 1.0)
        if m.region is not None:
            poly = np.asarray(m.region.polygon, dtype=np.float64).reshape(-1, 3)
            if len(poly) > shaders.MAX_POLYGON:
                raise WarpError(f"map {i} ({m.role}): its region polygon has {len(poly)} vertices; "
                                f"the shader takes at most {shaders.MAX_POLYGON}")
            block[base + 6, 3] = len(poly)
            normal = np.asarray(m.region.normal, dtype=np.float64)
            block[base + 7] = (*normal, m.region.offset - normal @ o)
            block[base + 8, 0] = m.region.tolerance
            block[base + 9:base + 9 + len(poly), :3] = poly - o
            block[base + 9:base + 9 + len(poly), 3] = 1.0
    return block.astype(np.float32)


_dummies: dict = {}


def _dummy(fmt: str):
    import gpu
    tex = _dummies.get(fmt)
    if tex is None:
        tex = _dummies[fmt] = gpu.types.GPUTexture((1, 1), format=fmt)
    return tex


def shading_pass(view: View, light: Light, setup: ShadowSetup, shadow: ShadowSettings, geometry, table,
                 batches: BatchCache, maps: list, resolution: tuple[int, int], albedo: float = DEFAULT_ALBEDO,
                 origin=(0.0, 0.0, 0.0), spot_blend: float = 0.0):
    """Camera pass: depth pre-pass, then shading with LESS_EQUAL. Returns the
    framebuffer and its three colour textures (direct, data, world position
    relative to ``origin``)."""
    import gpu
    w, h = resolution
    direct = gpu.types.GPUTexture((w, h), format="RGBA32F")
    data = gpu.types.GPUTexture((w, h), format="RGBA32F")
    world = gpu.types.GPUTexture((w, h), format="RGBA32F")
    depth = gpu.types.GPUTexture((w, h), format="DEPTH_COMPONENT32F")
    fb = gpu.types.GPUFrameBuffer(depth_slot=depth, color_slots=(direct, data, world))
    view_proj = _gl_matrix(relative(view.world_to_clip, origin))
    mdsm = shadow.mdsm_depths > 1
    ubo = gpu.types.GPUUniformBuf(shade_block(view, light, setup, shadow, albedo, origin, spot_blend).tobytes())
    with fb.bind():
        gpu.state.viewport_set(0, 0, w, h)
        fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        pre = shaders.prepass_shader()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)
        gpu.state.color_mask_set(False, False, False, False)
        pre.bind()
        pre.uniform_float("u_view_proj", view_proj)
        draw_table(pre, batches, geometry, table)
        gpu.state.color_mask_set(True, True, True, True)
        gpu.state.depth_mask_set(False)
        sh = shaders.shade_shader(mdsm, len(setup.maps))
        sh.bind()
        sh.uniform_float("u_view_proj", view_proj)
        sh.uniform_block("lixel", ubo)
        dummy = _dummy("RGBA32F" if mdsm else "DEPTH_COMPONENT32F")
        for i in range(shaders.MAX_MAPS):
            sh.uniform_sampler(f"u_map{i}", maps[i][0] if i < len(maps) else dummy)
        draw_table(sh, batches, geometry, table)
        gpu.state.depth_test_set("NONE")
    return fb, (direct, data, world)


def read_color(fb, slot: int, size: tuple[int, int]) -> np.ndarray:
    """(H, W, 4) float32, row 0 at the bottom."""
    w, h = size
    out = np.empty((h, w * 4), dtype=np.float32)
    with fb.bind():
        fb.read_color(0, 0, w, h, 4, slot, "FLOAT", data=_buffer(out))
    return out.reshape(h, w, 4)


def read_depth(fb, size: tuple[int, int]) -> np.ndarray:
    """(H, W) float32 window depth, row 0 at the bottom."""
    w, h = size
    out = np.empty((h, w), dtype=np.float32)
    with fb.bind():
        fb.read_depth(0, 0, w, h, data=_buffer(out))
    return out


def eye_space_blur(shadow: np.ndarray, eye_depth: np.ndarray, covered: np.ndarray, radius: float) -> np.ndarray:
    """Depth-dependent eye-space blur of the shadow image (Scherzer §4.3): a box
    blur whose radius is ``radius`` pixels at the nearest visible surface and
    falls as 1 / eye depth, so near shadows (where projection aliasing is
    large on screen) are blurred most and distant detail is kept. Only covered
    pixels contribute."""
    if radius <= 0 or not covered.any():
        return shadow
    d = np.where(covered, eye_depth, np.inf)
    d_near = float(d[covered].min())
    r_px = np.where(covered, radius * d_near / np.maximum(d, d_near), 0.0)
    levels = np.rint(r_px).astype(np.int64)
    out = shadow.copy()
    wgt = covered.astype(np.float64)
    val = shadow.astype(np.float64) * wgt

    def box(img, r):
        p = np.pad(img, r, mode="constant")
        c = np.cumsum(np.cumsum(p, 0), 1)
        c = np.pad(c, ((1, 0), (1, 0)))
        k = 2 * r + 1
        return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]

    for r in range(1, int(levels.max()) + 1):
        sel = levels == r
        if not sel.any():
            continue
        num, den = box(val, r), box(wgt, r)
        out[sel] = (num[sel] / np.maximum(den[sel], 1e-12)).astype(out.dtype)
    return out


def footprint_heatmap(texels_per_pixel: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """RGBA heatmap of shadow-map texels per screen pixel (the square root of the
    Jacobian determinant of texel over pixel coordinates): red below 1 (a texel
    covers several pixels: undersampled, aliasing), green at 1, blue above
    (oversampled). Colour = log2 ratio clamped to [-4, 4]."""
    t = np.clip(np.log2(np.maximum(texels_per_pixel, 1e-6)) / 4.0, -1.0, 1.0)
    rgba = np.zeros(texels_per_pixel.shape + (4,), dtype=np.float32)
    rgba[..., 0] = np.clip(-t, 0, 1)
    rgba[..., 1] = 1.0 - np.abs(t)
    rgba[..., 2] = np.clip(t, 0, 1)
    rgba[..., 3] = 1.0
    rgba[~covered] = (0.0, 0.0, 0.0, 1.0)
    return rgba


def _shadow_settings(settings) -> ShadowSettings:
    if settings is None:
        return LixelSettings().shadow
    if isinstance(settings, ShadowSettings):
        return settings
    return settings.shadow


def render_shadows(view: View, light: Light, setup: ShadowSetup, geometry, settings=None,
                   resolution: Optional[tuple[int, int]] = None, *, body=None,
                   batches: Optional[BatchCache] = None, ambient=DEFAULT_AMBIENT, albedo: float = DEFAULT_ALBEDO,
                   spot_blend: float = 0.0, read_maps: bool = True) -> dict:
    """Render ``geometry`` from ``view`` with the shadow maps of ``setup``.

    Needs a GPU context (``addon.gpu.context.ensure_gpu_context()``; inside a
    RenderEngine with ``bl_use_gpu_context`` it already exists).

    ``geometry``: an ``addon.scene.geometry.SceneGeometry`` (from
    ``GeometryCache.update(depsgraph)`` or ``SceneGeometry.from_arrays``).
    ``settings``: ``LixelSettings`` or ``ShadowSettings`` (bias, PCF, MDSM, blur);
    default ``LixelSettings()``. ``resolution``: (w, h), default
    ``view.resolution``. ``body``: the intersection body if already computed
    (it culls casters); computed from the geometry's boxes otherwise.
    ``batches``: a ``BatchCache`` (default: the process-wide one).
    ``ambient``: world colour; ``albedo``: surface grey; ``spot_blend``: a spot
    light's Blender ``spot_blend`` (softness of the cone edge, 0 = hard).

    Returns a dict; images are float32 numpy arrays with row 0 at the bottom
    (Blender's render-result order):
      combined (H,W,4)            ambient + direct * (1 - shadow), world colour behind
      shadow_mask (H,W)           0 lit .. 1 fully shadowed (after the eye blur)
      shadow_raw (H,W)            the same before the eye blur
      covered (H,W) bool          a surface is visible
      world_position (H,W,3)      float64 (computed in float32 relative to the camera), NaN off-surface
      eye_depth (H,W)             distance along the view direction
      map_index (H,W) int         map used (-1: none serves the point / not covered)
      texels_per_pixel (H,W)      shadow-map footprint; footprint_heatmap (H,W,4)
      shadow_maps [ (h,w) ]       window depth per map (if read_maps)
      mdsm_keys [ (h,w,4) ]       n-depth keys per map when n > 1 (if read_maps)
      timings {stage: seconds}    upload, depth_pass, mdsm, shading, readback, compose
      counts {...}                casters drawn/culled, triangles, uploads
      memory {...}                bytes per map, per MDSM layer, render targets
    """
    shadow = _shadow_settings(settings)
    if not setup.maps:
        raise WarpError("the shadow setup has no maps")
    if len(setup.maps) > shaders.MAX_MAPS:
        raise WarpError(f"the shadow setup has {len(setup.maps)} maps; Lixel's shader takes at most {shaders.MAX_MAPS}")
    w, h = resolution or view.resolution
    batches = batches if batches is not None else shared_batches()
    timings: dict = {}
    t = time.perf_counter()

    inst = geometry.instances
    boxes = inst.world_boxes()
    casts = inst.casts.copy()
    if body is None:
        try:
            body = intersection_body(view, light, SceneBounds(boxes[casts], boxes[inst.receives]))
        except EmptyBodyError as exc:
            log.info("Lixel: %s; nothing casts a visible shadow", exc)
            body = None
    caster_mask = np.zeros(len(inst), dtype=bool)
    if body is not None and casts.any():
        caster_mask[casts] = boxes_meeting(body.hull_planes, boxes[casts], body.tolerance * 10)
    view_planes = face_planes(hexahedron_faces(view.corners()))
    receiver_mask = inst.receives & boxes_meeting(view_planes, boxes, 1e-9 * max(view.far, 1.0))

    uploads_before, tris_before = batches.uploads, batches.uploaded_triangles
    for k in {inst.keys[i] for i in np.flatnonzero(caster_mask | receiver_mask)}:
        batches.get(geometry.meshes[k])
    origin = view.position  # the GPU works in float32 relative to the camera
    casters = instance_table(geometry, caster_mask, origin)
    receivers = instance_table(geometry, receiver_mask, origin)
    timings["upload"] = time.perf_counter() - t

    t = time.perf_counter()
    maps = depth_pass(setup, geometry, casters, shadow, batches, origin=origin)
    _sync(maps[-1][1])
    timings["depth_pass"] = time.perf_counter() - t

    t = time.perf_counter()
    keys = mdsm_pass(maps, setup, shadow) if shadow.mdsm_depths > 1 else None
    if keys:
        _sync(keys[-1][1], color=True)
    timings["mdsm"] = time.perf_counter() - t

    t = time.perf_counter()
    fb, _ = shading_pass(view, light, setup, shadow, geometry, receivers, batches, keys or maps, (w, h), albedo,
                         origin, spot_blend)
    _sync(fb, color=True)
    timings["shading"] = time.perf_counter() - t

    t = time.perf_counter()
    direct = read_color(fb, 0, (w, h))
    data = read_color(fb, 1, (w, h))
    world = read_color(fb, 2, (w, h))
    shadow_maps = [read_depth(f, tuple(int(v) for v in m.size)) for (_, f), m in zip(maps, setup.maps)] if read_maps else []
    mdsm_keys = [read_color(f, 0, tuple(int(v) for v in m.size)) for (_, f), m in zip(keys, setup.maps)] \
        if (keys and read_maps) else []
    timings["readback"] = time.perf_counter() - t

    t = time.perf_counter()
    covered = direct[..., 3] > 0.5
    raw = np.where(covered, data[..., 0], 0.0).astype(np.float32)
    eye_depth = data[..., 3]
    mask = eye_space_blur(raw, eye_depth, covered, shadow.eye_blur)
    amb = np.asarray(ambient, dtype=np.float32)
    combined = np.empty((h, w, 4), dtype=np.float32)
    lit = direct[..., :3] * (1.0 - mask[..., None]) + albedo * amb
    combined[..., :3] = np.where(covered[..., None], lit, amb)
    combined[..., 3] = 1.0
    tpp = np.where(covered, data[..., 2], 0.0).astype(np.float32)
    world_pos = np.where(covered[..., None], world[..., :3] + origin, np.nan)
    map_index = np.where(covered, np.rint(data[..., 1]), -1).astype(np.int32)
    timings["compose"] = time.perf_counter() - t

    map_bytes = [int(m.size[0]) * int(m.size[1]) * 4 for m in setup.maps]
    counts = {
        "maps": len(setup.maps),
        "instances": len(inst),
        "casters_drawn": int(caster_mask.sum()),
        "casters_culled": int((casts & ~caster_mask).sum()),
        "non_casters": int((~casts).sum()),
        "caster_triangles_drawn": casters.triangle_count,
        "caster_triangles_culled": int(sum(geometry.meshes[inst.keys[i]].triangle_count
                                           for i in np.flatnonzero(casts & ~caster_mask))),
        "receivers_drawn": int(receiver_mask.sum()),
        "receiver_triangles_drawn": receivers.triangle_count,
        "uploads": batches.uploads - uploads_before,
        "uploaded_triangles": batches.uploaded_triangles - tris_before,
    }
    memory = {
        "per_map_bytes": map_bytes,
        "mdsm_bytes_per_layer": [b for b in map_bytes] if keys else [],
        "mdsm_texture_bytes": [b * 4 for b in map_bytes] if keys else [],
        "render_target_bytes": w * h * (3 * 16 + 4),
    }
    return {
        "combined": combined,
        "shadow_mask": mask,
        "shadow_raw": raw,
        "covered": covered,
        "world_position": world_pos,
        "eye_depth": np.where(covered, eye_depth, np.inf).astype(np.float32),
        "map_index": map_index,
        "texels_per_pixel": tpp,
        "footprint_heatmap": footprint_heatmap(tpp, covered),
        "shadow_maps": shadow_maps,
        "mdsm_keys": mdsm_keys,
        "timings": timings,
        "counts": counts,
        "memory": memory,
    }
