"""Lixel renders for the UI and the scripts, through the gpu pipeline's public
``addon.gpu.pipeline.render_shadows``: the shadowed scene and the shadow map
picture-in-picture, the comparison mosaic of every method, PNG output and image files read back.

Images are float32 numpy (H, W, 4) with row 0 at the bottom (Blender's order).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..gpu.blas import one_blas_thread
from ..scene.owned import find_made, mark_made
from ..scene.units import length_text
from .live import LiveState, scene_geometry


def render_state(st: LiveState, depsgraph, resolution, setup=None, settings=None, geometry=None,
                 read=("combined", "shadow_mask", "shadow_maps")):
    """Render the state's camera view with ``setup`` (default: the state's):
    an ``addon.gpu.result.RenderResult`` holding the images in ``read``, shadowed as F12 shadows the frame
    (:func:`as_rendered`), transparent where F12 is (Film Transparent: the scripts drew the world there, 969 of 5184
    pixels differed). Starts the GPU context when needed (background mode); raises WarpError
    (GPUUnavailableError) with a message for the user."""
    from ..gpu.context import ensure_gpu_context
    from ..gpu.pipeline import render_shadows
    ensure_gpu_context()
    geometry = geometry if geometry is not None else scene_geometry(depsgraph)
    setup, body, links = as_rendered(st, depsgraph, geometry, setup if setup is not None else st.setup)
    transparent = bool(depsgraph.scene_eval.render.film_transparent)   # as F12: (0, 0, 0, 0) where no surface is
    return render_shadows(st.view, st.light, setup, geometry, settings if settings is not None else st.settings,
                          tuple(int(v) for v in resolution), body=body, read=read, lit=links.lit, blocks=links.blocks,
                          transparent=transparent, **lighting(st, depsgraph))


def as_rendered(st: LiveState, depsgraph, geometry, setup) -> tuple:
    """(setup, body, LightLinks) that draw the state's frame as F12 does (``addon.render.engine``): no shadow where
    the light's Shadow is off (``describe.shadow_off``), and the light's Light and Shadow Linking followed. Without
    them ``render_method.py`` shadowed the frame of a light with Shadow off, and drew the shadow of a cube its Shadow
    Linking left out and lit one its Light Linking left unlit, where F12 and Cycles do not (29 and 198 pixels of a
    96x54 picture differed)."""
    from ..render.engine import no_shadow_setup
    from ..scene.describe import shadow_off
    from ..scene.linking import LightLinks, light_links
    lob = state_light(st, depsgraph)
    links = LightLinks()
    if len(geometry.instances.linkers):     # a light has Light/Shadow Linking: follow the picture's light's
        links = light_links(lob.original if lob is not None else None, geometry.instances)
    if shadow_off(lob):
        return no_shadow_setup(st.method_used or "uniform"), None, links
    return setup, st.body, links


def state_light(st: LiveState, depsgraph):
    """The evaluated object of the state's light (None where it is gone)."""
    return next((ob for ob in depsgraph.objects if ob.type == "LIGHT" and ob.original.as_pointer() == st.light_pointer),
                None)


def lighting(st: LiveState, depsgraph) -> dict:
    """What F12 gives the shading pass besides the light (``addon.render.engine``): the world's light as Cycles
    renders it (``scene.world.world_shading``: its light on surfaces and behind them) and the spot's blend, so that
    pictures lit from the live state (scripts, the 3D view's picture) are lit as renders of the same frame."""
    from ..scene.world import world_shading
    lob = state_light(st, depsgraph)
    blend = float(lob.data.spot_blend) if lob is not None and lob.data.type == "SPOT" else 0.0
    ambient, background = world_shading(depsgraph.scene_eval.world, view_layer=depsgraph.view_layer)
    return dict(ambient=ambient, background=background, spot_blend=blend)


def fit_resolution(resolution, longest: int) -> tuple[int, int]:
    """``resolution`` scaled so its longer side is ``longest`` pixels."""
    w, h = (int(v) for v in resolution)
    s = longest / max(w, h)
    return max(1, round(w * s)), max(1, round(h * s))


def depth_to_rgba(depth: np.ndarray) -> np.ndarray:
    """A window-depth map as a grey picture, stretched over the depths written
    (cleared texels, depth 1, show as a dark blue background)."""
    d = np.asarray(depth, dtype=np.float32)
    written = d < 1.0
    out = np.zeros(d.shape + (4,), dtype=np.float32)
    out[..., 3] = 1.0
    out[~written] = (0.05, 0.05, 0.15, 1.0)
    if written.any():
        lo, hi = float(d[written].min()), float(d[written].max())
        g = (d - lo) / (hi - lo) if hi > lo else np.full_like(d, 0.5)
        g = 1.0 - 0.85 * np.clip(g, 0.0, 1.0)  # near the light = bright
        out[written, :3] = g[written][:, None]
    return out


LABEL_LINE = 17
"""Pixels per text line of a tile label (blf size 13)."""
LABEL_BACKGROUND = (0.08, 0.08, 0.09, 1.0)


def label_strip(lines: list, width: int) -> np.ndarray:
    """A (len(lines) * LABEL_LINE + 6, width, 4) strip with ``lines`` of white
    text, drawn with blf off-screen (needs a GPU context)."""
    import blf
    import gpu
    import mathutils
    from ..warp.geometry import ortho_matrix
    h = len(lines) * LABEL_LINE + 6
    offscreen = gpu.types.GPUOffScreen(width, h)
    try:
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=LABEL_BACKGROUND)
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_identity()
                gpu.matrix.load_projection_matrix(mathutils.Matrix(ortho_matrix(0, width, 0, h, -1, 1).tolist()))
                gpu.state.blend_set("ALPHA")
                blf.size(0, 13)
                blf.color(0, 1.0, 1.0, 1.0, 1.0)
                for i, text in enumerate(lines):
                    blf.position(0, 5, h - 4 - (i + 1) * LABEL_LINE + 4, 0)
                    blf.draw(0, text)
                gpu.state.blend_set("NONE")
            out = np.empty((h, width * 4), dtype=np.float32)
            fb.read_color(0, 0, width, h, 4, 0, "FLOAT", data=gpu.types.Buffer("FLOAT", out.shape, out))
    finally:
        offscreen.free()
    rgba = out.reshape(h, width, 4)
    rgba[..., 3] = 1.0
    return rgba


def method_label(row: dict, scene, render_ms: Optional[float] = None) -> list:
    """Two lines naming a method's tile (a row of ``live.compare_methods``); n_opt, a distance, in ``scene``'s units."""
    deg = "—" if row.get("theta") is None else f"{math.degrees(row['theta']):.1f}°"
    warp = f"n_opt {length_text(row['n_opt'], scene)}" if row.get("n_opt") is not None else \
        (f"λ {row['lam']:.3g}" if row.get("lam") is not None else "no warp parameter")
    first = f"{row['method']}: {row.get('maps', '?')} map(s)" + (f", {render_ms:.0f} ms" if render_ms else "")
    if row.get("fallbacks"):
        first += ", FELL BACK"
    med, mx = row.get("footprint_median_px"), row.get("footprint_max_px")
    fp = "" if med is None else f", texel footprint {med:.2g} px (max {mx:.2g})"
    return [first, f"θ {deg}, {warp}{fp}"]


def mosaic(images: list, columns: int, gap: int = 4, background=(0.0, 0.0, 0.0, 1.0), labels=None) -> np.ndarray:
    """Equal-size (H, W, 4) images in a grid, first image top-left (rows bottom-up
    in memory); ``labels``: per image a list of text lines drawn in a strip above
    it (needs a GPU context)."""
    if labels is not None:
        width = images[0].shape[1]
        lines = max(len(lab) for lab in labels)
        images = [np.concatenate([img, label_strip(list(lab) + [""] * (lines - len(lab)), width)])
                  for img, lab in zip(images, labels)]
    h, w = images[0].shape[:2]
    rows = math.ceil(len(images) / columns)
    out = np.empty((rows * h + (rows - 1) * gap, columns * w + (columns - 1) * gap, 4), dtype=np.float32)
    out[:] = background
    for i, img in enumerate(images):
        r, c = divmod(i, columns)
        y0 = (rows - 1 - r) * (h + gap)
        x0 = c * (w + gap)
        out[y0:y0 + h, x0:x0 + w] = img
    return out


@one_blas_thread()
def pip_textures(st: LiveState, depsgraph, longest: int, want_map: bool, want_scene: bool, targets=None) -> dict:
    """The picture-in-picture images as GPU textures, drawn without a read-back:
    ``"scene"`` (the camera view shaded with Lixel's shadows) and ``"map"`` (the
    first shadow map as a grey picture, ``compose.map_picture``), each fitted
    to ``longest`` pixels. They live in ``targets`` (the viewport passes its
    own pool, so no other frame draws over them) until the next call; the pool is trimmed afterwards as a frame's
    is (``TargetPool.trim``: the viewport's pool kept the shadow maps, up to the memory guard's 4 GiB per scene)."""
    from ..gpu import compose
    from ..gpu.context import ensure_gpu_context
    from ..gpu.pipeline import ShadowFrame
    out = {}
    if not (want_map or want_scene):
        return out
    ensure_gpu_context()
    geometry = scene_geometry(depsgraph)
    setup, body, links = as_rendered(st, depsgraph, geometry, st.setup)
    frame = ShadowFrame(geometry, st.view, fit_resolution(st.view.resolution, longest),
                        read={"combined"}, targets=targets, lit=links.lit, blocks=links.blocks)
    try:
        frame.camera_prepass()
        frame.draw_maps(setup, st.settings.shadow, body)
        if want_scene:
            frame.shade(st.light, setup, st.settings.shadow, **lighting(st, depsgraph))
            out["scene"] = frame.combined_texture()
        if want_map and setup.maps[0].role != "none":   # a light with Shadow off has no map to show
            out["map"] = compose.map_picture(frame.targets, "map_picture", frame.maps[0][0], setup.maps[0].size,
                                             longest)
    finally:
        frame.targets.trim()    # what ``out`` holds lives on with it
    return out


def pip_images(st: LiveState, depsgraph, longest: int, want_map: bool, want_scene: bool) -> dict:
    """:func:`pip_textures` read back as float32 (H, W, 4) images."""
    from ..gpu import compose
    from ..gpu.targets import TargetPool
    pool = TargetPool()
    return {name: compose.read_color(pool.framebuffer(colors=(tex,)), 0, (tex.width, tex.height))
            for name, tex in pip_textures(st, depsgraph, longest, want_map, want_scene, pool).items()}


def compare_renders(st: LiveState, depsgraph, rows: list, longest: int = 320) -> tuple[np.ndarray, list]:
    """Render each computed method of ``rows`` (from ``live.compare_methods``) and
    put them in a mosaic (methods in row order, left to right, top to bottom).
    Returns (mosaic, [method names drawn])."""
    geometry = scene_geometry(depsgraph)
    res = fit_resolution(st.view.resolution, longest)
    images, names, labels = [], [], []
    for row in rows:
        if "setup" not in row:
            continue
        out = render_state(st, depsgraph, res, setup=row["setup"], geometry=geometry, read={"combined"})
        images.append(np.ascontiguousarray(out.combined, dtype=np.float32))
        names.append(row["method"])
        labels.append(method_label(row, depsgraph.scene, 1000.0 * sum(out.timings.values())))
    if not images:
        raise ValueError("no method produced a setup to render")
    return mosaic(images, columns=min(3, len(images)), labels=labels), names


def to_image(name: str, rgba: np.ndarray, existing_ok: bool = True, linear: bool = True, keep: bool = False):
    """Lixel's Image datablock ``name`` holding ``rgba`` (the one Lixel made before
    is reused or, at another size or kind, replaced; a user's image of that name
    is never touched). ``existing_ok=False``: always a new image. ``linear``: the
    values are scene-linear (a float image, shown and saved through the view
    transform); False: they are display colours already (an 8-bit sRGB image,
    saved as they are), as the viewport overlays draw them. ``keep``: the image stays in the saved file and in
    undo steps: packed (OpenEXR or PNG) with a fake user, as a generated image's pixels live only in memory and an
    image nobody uses is not saved."""
    import bpy
    h, w = rgba.shape[:2]
    img = find_made(bpy.data.images, name) if existing_ok else None
    if img is not None and (tuple(img.size) != (w, h) or img.is_float != linear):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = mark_made(bpy.data.images.new(name, w, h, alpha=True, float_buffer=linear), name)
    img.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    img.update()
    if keep:
        img.file_format = "OPEN_EXR" if linear else "PNG"
        img.pack()
        img.use_fake_user = True
    return img


def image_pixels(image) -> np.ndarray:
    """A Blender image's pixels as float32 (H, W, channels), row 0 at the bottom (Blender's order)."""
    w, h = image.size
    px = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, image.channels)


def load_pixels(path) -> np.ndarray:
    """The pixels of the image file at ``path`` (:func:`image_pixels`), read without leaving it in bpy.data."""
    import bpy
    image = bpy.data.images.load(str(path), check_existing=False)
    try:
        return image_pixels(image)
    finally:
        bpy.data.images.remove(image)


IMAGE_FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF"}
"""The picture a file name's ending asks for, as Blender's ``Image.file_format`` (a name without one: PNG)."""


def image_format(path: str) -> str:
    """The :data:`IMAGE_FORMATS` entry of ``path``'s ending (PNG without one); OSError (naming ``path``) for an
    ending Lixel does not write: a picture saved in another format under it would not open as what it says."""
    import os
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix and suffix not in IMAGE_FORMATS:
        raise OSError(0, f"Lixel writes {', '.join(IMAGE_FORMATS)} pictures, not {suffix}: end the name with one "
                         f"of those", str(path))
    return IMAGE_FORMATS.get(suffix, "PNG")


def within_border(render, image: np.ndarray) -> np.ndarray:
    """A whole frame's ``image`` (row 0 at the bottom) as F12 leaves it under ``render``'s Render Region (Output
    properties > Format > Render Region): cut to the region with Crop to Render Region (``engine.result_window``),
    else the whole frame, transparent black (0, 0, 0, 0) outside the region, as Cycles and Lixel's F12 save it.
    Without this ``render_method.py`` drew the whole frame (2592 of 5184 pixels differed from F12's under a
    region of half the width, and the size under Crop)."""
    from ..render.engine import result_window
    if not render.use_border:
        return image
    x0, y0, x1, y1 = result_window(render, image.shape[1], image.shape[0])
    if render.use_crop_to_border:
        return image[y0:y1, x0:x1]
    out = np.zeros_like(image)
    out[y0:y1, x0:x1] = image[y0:y1, x0:x1]
    return out


VIEW_SETTINGS = ("view_transform", "look", "exposure", "gamma", "use_white_balance", "white_balance_temperature",
                 "white_balance_tint")
"""The Color Management view settings F12 saves a picture through (``use_white_balance``...: 5.0 only)."""


def save_image(rgba: np.ndarray, path: str, name: Optional[str] = None, linear: bool = True, view_of=None) -> None:
    """Write an image (row 0 at the bottom) to a file in the format its ending names (:func:`image_format`: an
    OpenEXR keeps scene-linear values above 1); ``linear`` as in :func:`to_image`. ``view_of``: a scene whose Color
    Management (display, view transform, look, exposure, gamma) a scene-linear picture is saved through in a format
    other than OpenEXR, as F12 saves it (without it, 4066 of 5184 pixels of ``render_method.py``'s PNG differed
    from F12's under a new scene's AgX); None: sRGB-encoded as it is. OSError (naming
    ``path``) when it cannot be written. A relative ``path`` is the working directory's (Blender 5.0 cannot save to a
    bare file name such as "out.png": it fails to make its empty folder); "//" paths stay the .blend file's."""
    import os

    import bpy
    from ..cli.output import replacing
    file_format = image_format(path)
    final = bpy.path.abspath(str(path)) if str(path).startswith("//") else os.path.abspath(path)
    if os.path.isdir(final):
        raise OSError(21, "it is a folder: give a file name", str(path))
    os.makedirs(os.path.dirname(final), exist_ok=True)     # as Blender makes an output's folders
    img = to_image(name or "Lixel output", rgba, existing_ok=False, linear=linear)
    settings = None
    try:
        with replacing(final) as temporary:   # whole or not at all: a failed write leaves the file that was there
            img.filepath_raw = temporary
            img.file_format = file_format
            if linear and (file_format == "OPEN_EXR" or view_of is not None):
                # Image.save() does not write scene-linear values to OpenEXR (measured: 4.2.23 writes them sRGB-encoded,
                # 0.25 -> 0.537 and 2.0 -> 1.353; 5.0.1 wherever alpha < 1, 0.25 -> 0.589 at alpha 0.5); save_render
                # with OpenEXR settings writes them as they are, in both, and other formats through the settings'
                # Color Management. Its settings come from a scene of its own.
                settings = bpy.data.scenes.new("Lixel output settings")
                fmt = settings.render.image_settings
                fmt.file_format = file_format
                if file_format == "OPEN_EXR":
                    fmt.color_mode, fmt.color_depth = "RGBA", "32"
                else:
                    fmt.color_mode = "RGB" if file_format == "JPEG" else "RGBA"
                    settings.display_settings.display_device = view_of.display_settings.display_device
                    for attr in VIEW_SETTINGS:
                        if hasattr(view_of.view_settings, attr):
                            setattr(settings.view_settings, attr, getattr(view_of.view_settings, attr))
                img.save_render(temporary, scene=settings)
            else:
                img.save()
    except RuntimeError as exc:  # Blender's "Error: Could not write image: <why>" (or "internal error, see console")
        why = str(exc).strip().splitlines()[0].partition("Could not write image: ")[2]
        raise OSError(0, why if why and "internal error" not in why else "the image cannot be written there",
                      str(path)) from None
    finally:
        bpy.data.images.remove(img)
        if settings is not None:
            bpy.data.scenes.remove(settings)
