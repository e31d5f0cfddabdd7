"""Overlay snapshots: the viewport overlays drawn off-screen, with the
viewport's own draw code (:func:`.overlays.draw_scene_overlays`), from the
scene camera or from an outside observer that sees the whole setup.

A viewport draws its overlays over the scene it has already drawn, and tests
them against that scene's depth. Off-screen there is no scene, so
:func:`draw_snapshot` first draws one: every receiver triangle flat-shaded
grey by a headlight (like the viewport's solid mode), its depth pushed back by
:data:`BACKDROP_DEPTH_OFFSET` so that overlays lying on the surfaces pass the
depth test. Then the overlays are drawn exactly as in the viewport.

Used by ``scripts/overlay_snapshot.py`` (any scene), ``LIXEL_OT``-free in
background mode, and by the report (``bench/report/overlays.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..scene.units import length_text
from ..warp.geometry import frustum_matrix, look_along, normalize, translation

BACKDROP_DEPTH_OFFSET = 2e-4
"""NDC depth added to the backdrop (the stand-in for the viewport's scene depth)."""
BACKDROP_GREY = (0.42, 0.86)
"""Backdrop grey from facing away from the headlight to facing it."""
BACKGROUND = (0.16, 0.16, 0.17, 1.0)
"""Blender's default viewport background, roughly."""


@dataclass
class OverlayFlags:
    """Which overlays to draw (the same names as the scene's Lixel properties)."""

    show_body: bool = False
    show_frusta: bool = False
    show_warp: bool = False
    show_texels: bool = False
    show_footprint: bool = False
    body_alpha: float = 0.15

    @classmethod
    def of(cls, names) -> "OverlayFlags":
        """From names: body, frusta, warp, texels, footprint."""
        flags = cls()
        for n in names:
            attr = f"show_{n}"
            if not hasattr(flags, attr):
                raise ValueError(f"unknown overlay {n!r}; choose from body, frusta, warp, texels, footprint")
            setattr(flags, attr, True)
        return flags


# --- where to look from ----------------------------------------------------------------------------------------

def _points(a) -> np.ndarray:
    p = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    return p[np.all(np.isfinite(p), axis=1)]


def observer_view_projection(geometry: dict, view, aspect: float, fov_y: float = math.radians(35.0),
                             reach: float = 2.5, scene=None) -> tuple[np.ndarray, list]:
    """World -> clip of an observer outside the setup, and notes on what the
    picture leaves out.

    The picture is fitted to B (the view frustum when there is no B), and to
    the corners of the view frustum, the light frusta, the warp frustum and the
    points (the projection centre, B's centroid) that lie within ``reach``
    times B's radius of its centre: a camera's far plane, a warp frustum or a
    spot's post-perspective light frustum can reach hundreds of metres past
    the scene, and fitting them would shrink the scene to a dot. What is left
    out is named in the notes, with how far it reaches in ``scene``'s units
    (its lines still run out of the picture). The observer looks at the
    centre from the camera's right, a little behind it and above it (world Z up).
    """
    notes = []
    view_corners = _points(geometry["view_corners"])
    body = _points(geometry.get("body_edges", np.zeros((0, 3))))
    core = body if len(body) else view_corners
    centre = 0.5 * (core.min(axis=0) + core.max(axis=0))
    radius = float(np.max(np.linalg.norm(core - centre, axis=1))) or 1.0
    parts = [core]
    others = [("camera's view frustum", view_corners if len(body) else np.zeros((0, 3))),
              ("light frusta", geometry.get("light_lines", np.zeros((0, 3)))),
              ("warp frustum", geometry.get("warp_lines", np.zeros((0, 3))))]
    others += [(name.replace("_", " "), p) for name, p in geometry.get("points", {}).items()]
    for name, pts in others:
        p = _points(pts)
        if not len(p):
            continue
        d = np.linalg.norm(p - centre, axis=1)
        near = d <= reach * radius
        parts.append(p[near])
        if not near.all():
            notes.append(f"{name} reach{'' if name.endswith('frusta') else 'es'} {length_text(d.max(), scene)} from "
                         f"the setup's centre, beyond the picture")
    pts = np.concatenate(parts)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    radius = float(np.max(np.linalg.norm(pts - centre, axis=1))) or 1.0
    forward = np.asarray(view.direction, dtype=np.float64)
    up = np.array([0.0, 0.0, 1.0])
    flat = forward - up * (forward @ up)
    flat = normalize(flat) if np.linalg.norm(flat) > 1e-6 else np.array([0.0, 1.0, 0.0])
    right = np.cross(flat, up)
    towards_observer = normalize(1.0 * right - 0.55 * flat + 0.9 * up)
    half = min(fov_y, 2 * math.atan(math.tan(fov_y / 2) * aspect)) / 2
    distance = radius / math.sin(half) * 1.02
    eye = centre + towards_observer * distance
    world_to_eye = look_along(eye, centre - eye, up)
    near = max(distance - radius * 1.05, distance * 1e-3)
    far = distance + radius * 40.0  # lines that run out of the fitted sphere are still drawn
    return tight_frustum(pts, world_to_eye, aspect, near, far) @ world_to_eye, notes


def tight_frustum(points, world_to_eye: np.ndarray, aspect: float, near: float, far: float,
                  margin: float = 0.04) -> np.ndarray:
    """An off-centre perspective projection (glFrustum) whose window just holds
    ``points`` (all in front of the eye) plus ``margin`` on each side, widened
    along one axis to the picture's ``aspect`` (width / height)."""
    p = np.c_[np.asarray(points, dtype=np.float64), np.ones(len(points))] @ world_to_eye.T
    depth = np.maximum(-p[:, 2], 1e-9 * max(near, 1e-300))
    x, y = p[:, 0] / depth, p[:, 1] / depth            # tangents, the window at distance 1
    (x0, x1), (y0, y1) = (x.min(), x.max()), (y.min(), y.max())
    w, h = (x1 - x0) * (1 + 2 * margin), (y1 - y0) * (1 + 2 * margin)
    w, h = max(w, h * aspect, 1e-9), max(h, w / aspect, 1e-9)
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    return frustum_matrix((cx - w / 2) * near, (cx + w / 2) * near, (cy - h / 2) * near, (cy + h / 2) * near,
                          near, far)


def camera_view_projection(view) -> np.ndarray:
    """World -> clip of the scene camera (what Lixel's View holds)."""
    return np.asarray(view.world_to_clip, dtype=np.float64)


# --- drawing ---------------------------------------------------------------------------------------------------

def _flat_shaded(triangles: np.ndarray, eye: Optional[np.ndarray], direction: np.ndarray, origin) -> tuple:
    """Per-vertex positions (relative to ``origin``) and colours of grey triangles lit by a headlight."""
    t = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    to_eye = (eye[None, :] - t.mean(axis=1)) if eye is not None else -direction[None, :]
    to_eye /= np.maximum(np.linalg.norm(to_eye, axis=1, keepdims=True), 1e-300)
    lamb = np.abs(np.einsum("ij,ij->i", n, to_eye))
    lo, hi = BACKDROP_GREY
    g = lo + (hi - lo) * lamb
    colours = np.repeat(np.stack([g, g, g, np.ones_like(g)], axis=1), 3, axis=0)
    return (t - origin).reshape(-1, 3).astype(np.float32), colours.astype(np.float32)


def _eye_of(view_projection: np.ndarray):
    """(eye position or None for an orthographic view, view direction) of a world -> clip matrix."""
    inv = np.linalg.inv(view_projection)
    near, far = inv @ [0, 0, -1, 1], inv @ [0, 0, 1, 1]
    far3 = far[:3] / far[3]
    near3 = near[:3] / near[3]
    direction = normalize(far3 - near3)
    eye = None
    if np.linalg.norm(view_projection[3, :3]) > 1e-12:  # perspective: the eye has clip x = y = w = 0
        m = view_projection[[0, 1, 3], :3]
        rhs = -view_projection[[0, 1, 3], 3]
        try:
            eye = np.linalg.solve(m, rhs)
        except np.linalg.LinAlgError:
            eye = None
    return eye, direction


def draw_snapshot(scene, st, flags: OverlayFlags, view_projection: np.ndarray, size: tuple[int, int],
                  backdrop: bool = True) -> np.ndarray:
    """The overlays of ``st`` (a ``live.LiveState``) drawn off-screen from
    ``view_projection`` (world -> clip) into a ``size`` = (w, h) image; returns
    (h, w, 4) float32, row 0 at the bottom. Needs a GPU context."""
    import gpu
    import mathutils
    from gpu_extras.batch import batch_for_shader
    from . import overlays

    w, h = (int(v) for v in size)
    vp = np.asarray(view_projection, dtype=np.float64)
    offscreen = gpu.types.GPUOffScreen(w, h, format="RGBA16F")
    try:
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=BACKGROUND, depth=1.0)
            gpu.state.viewport_set(0, 0, w, h)
            if backdrop:
                tris = overlays.receiver_triangles_of(scene, st)
                if len(tris):
                    eye, direction = _eye_of(vp)
                    origin = overlays.triangles_origin(tris)   # as the overlays draw them (precision far out)
                    pos, col = _flat_shaded(tris, eye, direction, origin)
                    shader = overlays.builtin_shader("SMOOTH_COLOR", "3D_SMOOTH_COLOR")
                    batch = batch_for_shader(shader, "TRIS", {"pos": pos, "color": col})
                    pushed = np.eye(4)
                    pushed[2, 3] = BACKDROP_DEPTH_OFFSET  # z_clip += offset * w_clip: NDC depth + offset
                    with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                        gpu.matrix.load_identity()
                        drawn = pushed @ vp @ translation(origin)
                        gpu.matrix.load_projection_matrix(mathutils.Matrix(drawn.tolist()))
                        gpu.state.depth_test_set("LESS_EQUAL")
                        gpu.state.depth_mask_set(True)
                        batch.draw(shader)
                        gpu.state.depth_mask_set(False)
                        gpu.state.depth_test_set("NONE")
            overlays.draw_scene_overlays(scene, st, flags, vp)
            out = np.empty((h, w * 4), dtype=np.float32)
            fb.read_color(0, 0, w, h, 4, 0, "FLOAT", data=gpu.types.Buffer("FLOAT", out.shape, out))
    finally:
        offscreen.free()
    return out.reshape(h, w, 4)
