"""The gpu pipeline: shadow maps drawn with Blender's ``gpu`` module and the
camera's view shaded with them, the frame kept on the GPU until what is asked
for is read back. See docs/architecture.md.

A frame is a :class:`ShadowFrame`, run in the order its steps depend on::

    frame = ShadowFrame(geometry, view, resolution)   # the scene on the GPU (uploads what changed)
    frame.camera_prepass()                            # receivers in the view: depth, surface seen
    ...                                               # (the warp may read the pre-pass here)
    frame.draw_maps(setup, shadow, body)              # casters that can shadow what is seen; MDSM keys
    frame.shade(light, setup, shadow, ambient=...)    # one full-screen pass over the pre-pass surface
    result = frame.finish(read=...)                   # blur/preview on the GPU, read back once

:func:`render_shadows` runs all of it in one call (report, UI, tests). Each
step is timed (stages: upload (the GPU scene brought up to date), cull
(receivers to the view, casters to B's hull, their draw lists), camera_prepass,
depth_pass, mdsm, shading, compose, readback); ``ShadowFrame(..., timed=False)`` drops the per-stage
waits for the GPU (the render engine: one wait, at the read-back).
"""
from __future__ import annotations

import logging
import math
import time
from typing import Optional

import numpy as np

from ..settings import LixelSettings, ShadowSettings
from ..warp.body import intersection_body, view_frustum
from ..warp.culling import BoxIndex
from ..warp.geometry import UNIT_CUBE_CORNERS, clip_volume_corners, homogeneous, perpendicular, translation
from ..warp.types import EmptyBodyError, Light, ShadowSetup, View, WarpError
from . import compose, shaders
from .blas import one_blas_thread
from .batches import DrawList, GPUScene, shared_scene
from .layout import LIXEL_SHADE
from .result import ANALYSIS, SURFACE, RenderCounts, RenderMemory, RenderResult, check_read, unpack_normals
from .targets import TargetPool, check_map_memory, map_bytes, shared_targets

log = logging.getLogger(__name__)

DEFAULT_ALBEDO = 0.8
"""Grey of every surface (Blender's default material base colour)."""
DEFAULT_AMBIENT = (0.05, 0.05, 0.05)
"""World colour when none is given (Blender's default world)."""


def bias_vector(shadow: ShadowSettings) -> tuple[float, float, float, float]:
    """The shading pass's bias uniform (Scherzer §4.2), in texels of the
    receiver: (constant c, slope factor s or normal offset, PCF reach
    r = max(1, k/2), mode code); see gpu_shaders/shade_frag.glsl."""
    mode = shadow.bias_mode
    second = shadow.normal_offset if mode == "NORMAL_OFFSET" else shadow.slope_bias
    return (float(shadow.constant_bias), float(second), max(1.0, shadow.pcf_kernel / 2.0),
            float(shaders.BIAS_CODES[mode]))


def relative(matrix: np.ndarray, origin) -> np.ndarray:
    """A world -> clip matrix for coordinates relative to ``origin``
    (``M @ translation(origin)``). The GPU works in float32 around the scene's
    drawing origin (``batches.drawing_origin``), so scenes far from the world
    origin keep their precision."""
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

    The light lies on the map's central ray x = y = 0, on the side where the
    depth z/w falls (LESS; rises, GREATER). Both are read from the matrix's
    rows, not through its inverse: a point light's face whose near plane is
    1e-7 of the way to its far one has a z row equal to its w row to 7 digits,
    a matrix of condition 3e16 whose inverse unprojects every depth to one
    point (gen42_05_point_low_in_view's cascade at 4096², whose render stopped
    there). The triangle lies on the central ray where w > 0 (at the ray's
    point nearest the world origin, else where w = 1), across it, 1e-3 of its
    distance to the plane w = 0 wide, so all of it has w > 0. A wider one can
    reach w < 0, where it projects mirrored: 1e-3 of the distance to the light
    wide, or on a map with parallel rays and a w that grows across them (a
    sun's warped maps) 1e-3 of |row 0 x row 1| (no length at all: it grows as
    1 / the scene's size squared), it culled the faces towards the light in 29
    of the 714 maps of tests.warp.golden (outdoor_sun's PSM and GLPR, the
    bench spot's GMNPR, ...) and in the LiSPSM, GMNPR and GLPR sun maps of a
    scene 1 cm wide, which lost each box's shadow on its own dark side.
    """
    m = np.asarray(shadow_map.matrix, dtype=np.float64)
    ray = np.cross(m[0, :3], m[1, :3])
    on_ray = np.linalg.lstsq(m[:2, :3], -m[:2, 3], rcond=None)[0]
    (z, w), (dz, dw) = m[2:] @ np.append(on_ray, 1.0), m[2:, :3] @ ray
    away = ray * np.sign(dz * w - z * dw) * (-1.0 if shadow_map.depth_test == "GREATER" else 1.0)  # d(z/w)·w²
    size = float(np.linalg.norm(away))
    if not (np.isfinite(size) and size > 0.0):
        return False  # a degenerate map draws nothing: no winding to speak of
    perspective = abs(dw) > 1e-12 * np.linalg.norm(m[3, :3]) * size
    near = on_ray if w > 0.0 or not perspective else on_ray + ray * (1.0 - w) / dw   # (w = 1 there)
    slope = float(np.linalg.norm(m[3, :3]))   # |grad w|: the plane w = 0 lies |w| / slope from a point
    width = 1e-3 * (abs(m[3] @ np.append(near, 1.0)) / slope if slope > 0.0 else float(np.linalg.norm(near)) or 1.0)

    def project(p):
        h = m @ np.append(p, 1.0)
        return h[:2] / h[3]

    n = -away / size  # towards the light
    u = perpendicular(n)
    v = np.cross(n, u)  # u x v = n
    a = project(near)
    b, c = project(near + u * width), project(near + v * width)
    area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return bool(area < 0)


def is_affine(matrix) -> bool:
    """Whether a light matrix has a constant w (an orthographic map: a sun's
    unwarped map), so that everything affine in the world position is also
    affine in its window coordinates."""
    w = np.asarray(matrix, dtype=np.float64)[3]
    return bool(np.all(np.abs(w[:3]) <= 1e-12 * abs(w[3])) and w[3] != 0.0)


def depth_draw(shadow_map, origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """How the depth pass draws one map, relative to ``origin``: (the matrix
    for ``gl_Position``, the window depth row for ``gl_FragDepth`` or None).

    * No depth row (hyperbolic z): the map's matrix, nothing written per fragment.
    * A depth row and an affine matrix: the linear depth is affine in the
      window coordinates, so the matrix's z row is replaced by the depth row
      (times the constant w) and the rasterizer interpolates it exactly: a bare
      draw with early depth testing.
    * A depth row and a projective matrix (warped maps, point and spot lights):
      the matrix as it clips (:func:`clip_matrix`), and the window depth row
      0.5 r + (0, 0, 0, 0.5) written per fragment (Scherzer §4.2's linear z).
    """
    matrix = relative(shadow_map.matrix, origin)
    if shadow_map.depth_row is None:
        return matrix, None
    row = relative_row(shadow_map.depth_row, origin)
    if is_affine(matrix):
        matrix = matrix.copy()
        matrix[2] = matrix[3, 3] * row
        return matrix, None
    return clip_matrix(shadow_map, origin), 0.5 * row + np.array([0.0, 0.0, 0.0, 0.5])


def clip_matrix(shadow_map, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The map's matrix as the depth pass and the shading clip with it, relative to ``origin``. With a depth row on
    a projective matrix its z row only clips, and is halved: a point or spot light's frame has hyperbolic z with its
    near plane at the light, which puts everything seen within 1e-4 of the far plane z = w (gen2_03_spot: all of it
    at 1 to 1e-6), where float32 clipping drops casters and receivers at random (speckled false light); halved, it
    lies about z = w/2."""
    matrix = relative(shadow_map.matrix, origin)
    if shadow_map.depth_row is None or is_affine(matrix):
        return matrix
    return np.diag([1.0, 1.0, 0.5, 1.0]) @ matrix


NEAR_MARGIN = 1e-5
"""How far beyond a view's near plane (NDC depth) a solid must lie to have its back faces culled."""


def clear_of(face: np.ndarray, boxes: np.ndarray, margin: float) -> np.ndarray:
    """Whether each of ``boxes`` ((N, 2, 3) world AABBs) stays ``margin`` away
    from the convex planar polygon ``face`` ((4, 3) corners in order), by a
    separating axis: a box axis, the face's normal, or one across a box axis
    and a face edge."""
    edges = np.roll(face, -1, axis=0) - face
    axes = np.concatenate([np.eye(3), np.cross(edges[0], edges[1])[None],
                           np.cross(np.eye(3)[:, None], edges[None]).reshape(-1, 3)])
    reach = margin * np.linalg.norm(axes, axis=1)
    on_face = face @ axes.T
    centre, radius = (boxes.sum(axis=1) / 2) @ axes.T, ((boxes[:, 1] - boxes[:, 0]) / 2) @ np.abs(axes).T
    return np.any((centre + radius < on_face.min(axis=0) - reach) | (centre - radius > on_face.max(axis=0) + reach),
                  axis=1)


def seen_from_outside(geometry, matrix, greater: bool = False, among: Optional[np.ndarray] = None) -> np.ndarray:
    """Instances (of the mask ``among``, default all) whose back faces a
    view cannot see, as a mask: their mesh bounds solids
    (``MeshData.bounds_solids``) and the view's near plane (clip matrix
    ``matrix``: NDC depth -1, or +1 for a reversed, ``greater`` depth) clips
    none of them open where the view looks: their box stays clear of the near
    face by the face's size (:func:`clear_of`), or they lie
    wholly beyond the near plane by :data:`NEAR_MARGIN` (w > 0 at the corners
    of their local box, or else at all their vertices). Every ray of the view,
    starting on the near face, then meets one of their front faces before any
    of their back faces."""
    inst = geometry.instances
    solid = np.array([geometry.meshes[k].bounds_solids for k in inst.key_list], dtype=bool)[inst.key_ids]
    if among is not None:
        solid &= among
    try:
        face = clip_volume_corners(matrix)[slice(4, 8) if greater else slice(0, 4)]
    except np.linalg.LinAlgError:
        return np.zeros(len(inst), dtype=bool)
    if not np.all(np.isfinite(face)):
        return np.zeros(len(inst), dtype=bool)
    ids = np.flatnonzero(solid)
    ids = ids[~clear_of(face, inst.world_boxes()[ids], float(np.ptp(face, axis=0).max()))]
    to_clip = np.asarray(matrix, dtype=np.float64) @ inst.matrices[ids]                 # (n, 4, 4)
    lo, hi = inst.key_boxes[inst.key_ids[ids], 0], inst.key_boxes[inst.key_ids[ids], 1]
    corners = (lo + hi)[:, None] / 2 + (hi - lo)[:, None] / 2 * UNIT_CUBE_CORNERS[None]   # (n, 8, 3)
    sign = -1.0 if greater else 1.0

    def beyond(h):
        return np.all((h[..., 3] > 0) & (sign * h[..., 2] > (NEAR_MARGIN - 1.0) * h[..., 3]), axis=-1)
    near = ~beyond(np.einsum("nij,nkj->nki", to_clip, homogeneous(corners).reshape(-1, 8, 4)))
    for key in np.unique(inst.key_ids[ids[near]]):     # the box reaches the near plane: its triangles may not
        positions = homogeneous(geometry.meshes[inst.key_list[key]].positions)
        which = np.flatnonzero(near & (inst.key_ids[ids] == key))
        for part in np.array_split(which, -(-len(which) * len(positions) // (1 << 20))):
            near[part] = ~beyond(np.einsum("nij,vj->nvi", to_clip[part], positions))
    solid[ids[near]] = False
    return solid


def depth_pass(setup: ShadowSetup, scene: GPUScene, casters, shadow: ShadowSettings,
               targets: Optional[TargetPool] = None, bare: bool = False, solids: Optional[list] = None,
               prefix: str = "map") -> list:
    """Draw every map of ``setup``: returns [(depth texture, framebuffer)].

    Per map: clear to 1 (LESS) or 0 (GREATER, reversed test), depth test
    LESS_EQUAL / GREATER_EQUAL with the depth mask on; back-face rendering
    culls the faces that face the light (Scherzer §4.2); the depth stored is
    the map's linear depth row where it has one (:func:`depth_draw`). Biasing
    is applied where depths are compared (shading pass), so otherwise this is
    a bare draw. ``casters``: the ``DrawList`` every map draws, or one per
    map; ``solids`` (without back-face rendering): per map, the casters it
    sees as solids from outside (:func:`seen_from_outside`), drawn with their
    faces turned from the light culled, which their light-facing faces hide:
    the same map, less drawn. ``bare`` (the benchmarks' reference) draws
    every map with its own matrix and an empty fragment stage, culling no
    face but those of ``solids`` where given.
    Matrices are made relative to ``scene.origin`` (see :func:`relative`).
    Map i draws into the pool's depth texture "<prefix><i>".
    """
    import gpu
    targets = targets if targets is not None else shared_targets()
    origin = scene.origin
    out = []
    for i, m in enumerate(setup.maps):
        w, h = (int(v) for v in m.size)
        tex = targets.texture(f"{prefix}{i}", (w, h), "DEPTH_COMPONENT32F")
        fb = targets.framebuffer(depth=tex)
        greater = m.depth_test == "GREATER"
        matrix, window_row = (relative(m.matrix, origin), None) if bare else depth_draw(m, origin)
        shader = shaders.depth_shader(window_row is not None)
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            fb.clear(depth=0.0 if greater else 1.0)
            gpu.state.depth_test_set("GREATER_EQUAL" if greater else "LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            shader.bind()
            shader.uniform_float("u_light", _gl_matrix(matrix))
            if window_row is not None:
                shader.uniform_float("u_depth_row", tuple(float(v) for v in window_row))
            cull = "FRONT" if (shadow.back_faces and not bare) else "NONE"
            flip = light_facing_winds_clockwise(m)
            if solids is not None and cull == "NONE":
                scene.draw(shader, solids[i], cull="BACK", flip=flip)
            scene.draw(shader, casters[i] if isinstance(casters, list) else casters, cull=cull, flip=flip)
            gpu.state.depth_mask_set(False)
            gpu.state.depth_test_set("NONE")
        out.append((tex, fb))
    return out


def _gl_matrix(m: np.ndarray):
    from mathutils import Matrix
    return Matrix(np.asarray(m, dtype=np.float64).tolist())


def mdsm_pass(maps: list, setup: ShadowSetup, shadow: ShadowSettings, targets: Optional[TargetPool] = None) -> list:
    """n-depth key maps (RGBA32F) from the depth maps (Pagot et al. §4.3)."""
    import gpu
    targets = targets if targets is not None else shared_targets()
    shader = shaders.mdsm_shader()
    out = []
    for i, ((depth, _), m) in enumerate(zip(maps, setup.maps)):
        w, h = (int(v) for v in m.size)
        keys = targets.texture(f"keys{i}", (w, h), "RGBA32F")
        fb = targets.framebuffer(colors=(keys,))
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            gpu.state.depth_test_set("NONE")
            shader.bind()
            shader.uniform_sampler("u_depth", depth)
            shader.uniform_float("u_params", (float(shadow.mdsm_depths), float(shadow.mdsm_neighbourhood),
                                              1.0 if shadow.mdsm_selection == "SORT" else 0.0,
                                              1.0 if m.depth_test == "GREATER" else 0.0))
            compose.fullscreen_batch().draw(shader)
        out.append((keys, fb))
    return out


def shade_block(view: View, light: Light, setup: ShadowSetup, shadow: ShadowSettings,
                albedo: float = DEFAULT_ALBEDO, origin=(0.0, 0.0, 0.0), spot_blend: float = 0.0,
                ambient=DEFAULT_AMBIENT, resolution=None) -> np.ndarray:
    """The shading pass's uniform block (``layout.LIXEL_SHADE``) as float32
    rows, positions relative to ``origin``; ``resolution``: the frame's (w, h)
    (default ``view.resolution``)."""
    o = np.asarray(origin, dtype=np.float64)
    resolution = view.resolution if resolution is None else resolution
    b = LIXEL_SHADE.block()
    b.camera[:] = (*(view.position - o), 1.0 if view.orthographic else 0.0)
    mirrored = np.linalg.det(view.camera_to_world[:3, :3]) < 0       # a negatively scaled camera: shade_frag.glsl
    b.view_dir[:] = (*view.direction, -1.0 if mirrored else 1.0)
    b.eye_row[:] = relative_row(view.world_to_camera[2], o)
    kind = {"SUN": 0.0, "POINT": 1.0, "SPOT": 2.0}[light.type]
    b.light_pos[:] = (*((light.position - o) if light.position is not None else (0, 0, 0)), kind)
    cos_half = math.cos(light.spot_angle / 2) if light.type == "SPOT" else -1.0
    b.light_dir[:] = (*(light.direction if light.direction is not None else (0, 0, -1)), cos_half)
    b.light_color[:] = (*(np.asarray(light.color, dtype=np.float64) * light.energy), albedo)
    b.spot[0] = min(max(float(spot_blend), 0.0), 1.0)
    b.ambient[:3] = ambient
    b.bias[:] = bias_vector(shadow)
    b.inv_view_proj[:] = np.linalg.inv(relative(view.world_to_clip, o)).T   # columns
    b.screen[:2] = 2.0 / np.asarray(resolution, dtype=np.float64)
    for i, m in enumerate(setup.maps):
        bm = b.maps[i]
        bm.matrix[:] = clip_matrix(m, o).T  # columns
        if m.depth_row is not None:
            bm.depth_row[:] = relative_row(m.depth_row, o)
        bm.info[:] = (m.size[0], m.size[1], 1.0 if m.depth_test == "GREATER" else 0.0,
                      1.0 if m.depth_row is not None else 0.0)
        if m.view_depth_range is not None:
            bm.range[:3] = (m.view_depth_range[0], m.view_depth_range[1], 1.0)
            bm.extra[1] = m.blend_band                   # a cascade's seam: fades into the next map
        if m.region is not None:
            poly = np.asarray(m.region.polygon, dtype=np.float64).reshape(-1, 3)
            if len(poly) > shaders.MAX_POLYGON:
                raise WarpError(f"map {i} ({m.role}): its region polygon has {len(poly)} vertices; "
                                f"the shader takes at most {shaders.MAX_POLYGON}")
            bm.range[3] = len(poly)
            normal = np.asarray(m.region.normal, dtype=np.float64)
            bm.plane[:] = (*normal, m.region.offset - normal @ o)
            bm.extra[0] = m.region.tolerance
            bm.polygon[:len(poly), :3] = poly - o
            bm.polygon[:len(poly), 3] = 1.0
    return b.float32()


_dummies: dict = {}


def _dummy(fmt: str):
    import gpu
    tex = _dummies.get(fmt)
    if tex is None:
        tex = _dummies[fmt] = gpu.types.GPUTexture((1, 1), format=fmt)
    return tex


def _shadow_settings(settings) -> ShadowSettings:
    if settings is None:
        return LixelSettings().shadow
    if isinstance(settings, ShadowSettings):
        return settings
    return settings.shadow


def _view_planes(view: View) -> tuple[np.ndarray, np.ndarray]:
    frustum = view_frustum(view, np.zeros(3))
    return frustum.normals, frustum.offsets


class ShadowFrame:
    """One frame of the pipeline (see the module docstring for the order of
    the steps). ``geometry``: an ``addon.scene.geometry.SceneGeometry``;
    ``resolution``: (w, h), default ``view.resolution``; ``read``: the
    :class:`RenderResult` images the frame is for (what :meth:`shade` draws and
    :meth:`finish` reads back by default); ``scene``: the :class:`GPUScene`
    (default the process-wide one); ``targets``: the render targets (default
    the process-wide pool); ``lit``, ``blocks``: see ``self.lit``.
    """

    def __init__(self, geometry, view: View, resolution: Optional[tuple[int, int]] = None, *, read=ANALYSIS,
                 scene: Optional[GPUScene] = None, targets: Optional[TargetPool] = None, timed: bool = True,
                 lit: Optional[np.ndarray] = None, blocks: Optional[np.ndarray] = None):
        self.geometry = geometry
        self.lit, self.blocks = lit, blocks
        """The light's Light Linking and Shadow Linking, per instance (``addon.scene.linking.LightLinks``; None:
        all): the pre-pass marks the receivers it does not light, the maps draw only the casters that block it."""
        self.view = view
        self.read = check_read(read)
        w, h = resolution or view.resolution
        self.size = (int(w), int(h))
        self.scene = scene if scene is not None else shared_scene()
        self.targets = targets if targets is not None else shared_targets()
        self.timed = timed
        self.timings: dict = {}
        self.counts = RenderCounts(instances=len(geometry.instances))
        self._before = (self.scene.batches.uploads, self.scene.batches.uploaded_triangles,
                        self.scene.matrix_uploads, self.scene.list_uploads, self.targets.allocations)
        t = time.perf_counter()
        self.scene.sync(geometry)
        self.timings["upload"] = time.perf_counter() - t
        self.origin = self.scene.origin
        """Every position the GPU sees is relative to this point (float32 precision)."""
        self.receivers: Optional[DrawList] = None
        self.solids: Optional[DrawList] = None
        """The receivers the pre-pass draws as solids (their back faces culled); ``receivers`` the others."""
        self.marked: list = []
        """The receivers the pre-pass draws marked, per mark: (holdout, unlit, solids, others): the held-out ones,
        then the ones the light does not light (Light Linking); none in a scene without either, whose receivers
        are all in ``solids`` and ``receivers``."""
        self.map_solids: list = []
        """Per map, the casters it draws as solids (their faces turned from the light culled); none with
        back-face rendering, which culls the faces towards the light of every caster."""
        self.casters: Optional[DrawList] = None
        self.map_casters = None
        """What each map draws besides its solids: a list of ``DrawList`` per map (the casters it does not
        see as solids), or ``casters`` for every map; with ``map_solids``, what :func:`depth_pass` draws."""
        self.maps: list = []
        self.keys: list = []
        self.setup: Optional[ShadowSetup] = None
        self._depth = None
        self._surface = None
        self._shaded = None

    # ------------------------------------------------------------ steps

    @property
    def holds_out(self) -> bool:
        """Whether the pre-pass drew a held-out receiver (then the shading pass looks for them)."""
        return any(d.instance_count for held, _, *drawn in self.marked if held for d in drawn)

    @property
    def leaves_unlit(self) -> bool:
        """Whether the pre-pass drew a receiver the light does not light (then the shading pass looks for them)."""
        return any(d.instance_count for _, unlit, *drawn in self.marked if unlit for d in drawn)

    def _stage(self, name: str, t0: float, fb=None, color: bool = False) -> None:
        if self.timed and fb is not None:
            compose.sync(fb, color)
        self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - t0

    def _select(self, which: str, normals, offsets, tol: float) -> np.ndarray:
        """Instances of ``which`` ("casters" / "receivers") meeting the region, as a mask over all
        instances (kept by the scene for the same region: ``GPUScene.selection``)."""
        inst = self.geometry.instances
        normals, offsets = np.asarray(normals, dtype=np.float64), np.asarray(offsets, dtype=np.float64)

        def select():
            mask = np.zeros(len(inst), dtype=bool)
            sel = BoxIndex.of(inst.bounds, which).select(normals, offsets, tol)
            mask[inst.caster_ids if which == "casters" else inst.receiver_ids] = sel.mask
            return mask
        mask = self.scene.selection((which, normals.tobytes(), offsets.tobytes(), float(tol)), select)
        if which == "casters" and self.blocks is not None:   # Shadow Linking: only the light's blockers
            return mask & self.blocks
        return mask

    def _solids(self, mask: np.ndarray, matrix, greater: bool = False) -> np.ndarray:
        """The instances of ``mask`` that the view of clip matrix ``matrix``
        sees as solids from outside (:func:`seen_from_outside`); kept by the
        scene for the same view (``GPUScene.selection``)."""
        matrix = np.asarray(matrix, dtype=np.float64)
        return self.scene.selection(("solids", matrix.tobytes(), greater, mask.tobytes()),
                                    lambda: seen_from_outside(self.geometry, matrix, greater, mask))

    def camera_prepass(self):
        """Cull the receivers to the view frustum and draw them from the camera
        (``prepass_shader``): the depth and the surface seen (position, normal),
        which the shading pass shades; the back faces of solids seen from
        outside (:func:`seen_from_outside`: ``solids``, the others
        ``receivers``) are culled, as their front faces hide them: the same
        surface, ~1/3 less work on llvmpipe (docs/performance.md). Held-out
        receivers (``InstanceSet.holdouts``) are drawn after the others with
        ``prepass_shader(holdout=True)``, which marks their pixels: they hide what
        is behind them, and the shading pass leaves a transparent hole. So are the
        receivers the light does not light (Light Linking, ``self.lit``) with
        ``prepass_shader(unlit=True)``: the shading pass gives them no light and no
        shadow of it. Returns the
        camera depth texture (window depth, row 0 at the bottom; the visible
        region is read from it)."""
        import gpu
        if self._depth is not None:
            return self._depth
        t = time.perf_counter()
        view = self.view
        n, o = _view_planes(view)
        mask = self._select("receivers", n, o, 1e-9 * max(view.far, 1.0))
        solid = self._solids(mask, view.world_to_clip)
        inst, marks = self.geometry.instances, []   # the marked receivers are drawn apart
        if inst.any_holdout:
            marks.append((True, False, "held-out", inst.holdouts))
        if self.lit is not None and not self.lit.all():   # (a held-out one is a hole, lit or not)
            marks.append((False, True, "unlit", ~self.lit & ~inst.holdouts if inst.any_holdout else ~self.lit))
        self.marked = []
        for held, unlit, name, marked in marks:
            self.marked.append((held, unlit, self.scene.draw_list(f"{name} solid receivers", solid & marked,
                                                                  eye=view.position),
                                self.scene.draw_list(f"{name} receivers", mask & ~solid & marked, eye=view.position)))
            solid, mask = solid & ~marked, mask & ~marked
        self.solids = self.scene.draw_list("solid receivers", solid, eye=view.position)
        self.receivers = self.scene.draw_list("receivers", mask & ~solid, eye=view.position)
        drawn = [self.receivers, self.solids, *(d for _, _, *pair in self.marked for d in pair)]
        self.counts.receivers_drawn = sum(d.instance_count for d in drawn)
        self.counts.receiver_triangles_drawn = sum(d.triangle_count for d in drawn)
        self._view_proj = _gl_matrix(relative(view.world_to_clip, self.origin))
        self._stage("cull", t)
        t = time.perf_counter()
        w, h = self.size
        depth = self.targets.texture("camera_depth", self.size, "DEPTH_COMPONENT32F")
        surface = self.targets.texture("surface", self.size, "RGBA32F")
        fb = self.targets.framebuffer(depth=depth, colors=(surface,))
        pre = shaders.prepass_shader()
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            fb.clear(depth=1.0)              # the colour target is read only where depth was drawn
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            pre.bind()
            pre.uniform_float("u_view_proj", self._view_proj)
            r = self.view.world_to_camera[:3, :3]
            flip = bool(np.dot(np.cross(r[0], r[1]), r[2]) < 0)
            self.scene.draw(pre, self.solids, cull="BACK", flip=flip)
            self.scene.draw(pre, self.receivers)
            for held, unlit, solids, others in self.marked:
                if solids.instance_count or others.instance_count:
                    marking = shaders.prepass_shader(holdout=held, unlit=unlit)
                    marking.bind()
                    marking.uniform_float("u_view_proj", self._view_proj)
                    self.scene.draw(marking, solids, cull="BACK", flip=flip)
                    self.scene.draw(marking, others)
            gpu.state.depth_mask_set(False)
            gpu.state.depth_test_set("NONE")
        self._surface = surface
        self._depth = depth
        self._stage("camera_prepass", t, fb)
        return depth

    def draw_maps(self, setup: ShadowSetup, shadow: ShadowSettings, body=None) -> list:
        """Cull the casters to those that can shadow what the camera sees
        (B's light-extruded hull, ``body.hull_halfspaces``; none without a
        body) and draw the maps of ``setup`` (and their MDSM keys when
        ``shadow.mdsm_depths`` > 1), each culling the faces turned from the
        light of the solids it sees from outside (``map_solids``, see
        :func:`depth_pass`). Returns [(depth texture, framebuffer)]."""
        if not setup.maps:
            raise WarpError("the shadow setup has no maps")
        if len(setup.maps) > shaders.MAX_MAPS:
            raise WarpError(f"the shadow setup has {len(setup.maps)} maps; Lixel's shader takes at most "
                            f"{shaders.MAX_MAPS}")
        check_map_memory(setup, shadow.mdsm_depths > 1)
        t = time.perf_counter()
        inst = self.geometry.instances
        if body is not None and inst.casts.any():
            hn, ho = body.hull_halfspaces
            mask = self._select("casters", hn, ho, body.tolerance * 10)
        else:
            mask = np.zeros(len(inst), dtype=bool)
        self.casters = self.scene.draw_list("casters", mask)
        c = self.counts
        c.maps = len(setup.maps)
        c.casters_drawn = self.casters.instance_count
        culled = inst.casts & ~mask
        c.casters_culled = int(culled.sum())
        c.non_casters = int((~inst.casts).sum())
        c.caster_triangles_drawn = self.casters.triangle_count
        c.caster_triangles_culled = int(self.geometry.key_triangles[inst.key_ids[culled]].sum())
        self.map_casters, self.map_solids = self.casters, []
        if not shadow.back_faces:   # per map: the solids it sees from outside, and the other casters
            solid = [self._solids(mask, depth_draw(m)[0], m.depth_test == "GREATER") for m in setup.maps]
            self.map_solids = [self.scene.draw_list(f"solid casters {i}", s) for i, s in enumerate(solid)]
            self.map_casters = [self.scene.draw_list(f"casters {i}", mask & ~s) for i, s in enumerate(solid)]
        self._stage("cull", t)
        t = time.perf_counter()
        self.setup = setup
        self.maps = depth_pass(setup, self.scene, self.map_casters, shadow, self.targets,
                               solids=self.map_solids or None)
        self._stage("depth_pass", t, self.maps[-1][1])
        t = time.perf_counter()
        self.keys = mdsm_pass(self.maps, setup, shadow, self.targets) if shadow.mdsm_depths > 1 else []
        self._stage("mdsm", t, self.keys[-1][1] if self.keys else None, color=True)
        return self.maps

    def probe_depths(self, setup: ShadowSetup, body) -> list:
        """Draw ``setup``'s maps apart from the frame's own (depth textures "probe<i>") with every face of the
        casters that can shadow what the camera sees (``body.hull_halfspaces``), and read back their window depths,
        (h, w) each: a first look at where shadows fall (``addon.gpu.visibility.shadow_edges``)."""
        check_map_memory(setup)
        hn, ho = body.hull_halfspaces
        casters = self.scene.draw_list("casters", self._select("casters", hn, ho, body.tolerance * 10))
        maps = depth_pass(setup, self.scene, casters, ShadowSettings(), self.targets, prefix="probe")
        return [compose.read_depth(fb, tuple(int(v) for v in m.size)) for (_, fb), m in zip(maps, setup.maps)]

    def shade(self, light: Light, setup: ShadowSetup, shadow: ShadowSettings, albedo: float = DEFAULT_ALBEDO,
              spot_blend: float = 0.0, ambient=DEFAULT_AMBIENT, read=None, transparent: bool = False,
              background=None) -> None:
        """The shading pass: one full-screen pass over the surface the pre-pass
        saw (each pixel shaded once; no second draw of the receivers), writing
        only the targets the images in ``read`` come from
        (the :meth:`finish` that follows takes the same ``read``): the
        combined image (the unshadowed light when the eye-space blur follows),
        the shadow, the footprint heatmap, (shadow, map index, texels per
        pixel, eye depth), the surface seen (world position and normal).
        Where no surface is seen the combined image holds ``background`` (default ``ambient``, the world colour),
        alpha 1, or with ``transparent`` (Render properties > Film > Transparent) (0, 0, 0, 0). Where a held-out surface is
        seen the combined image is (0, 0, 0, 0) either way, as in Cycles, and every other image holds what it holds
        where nothing is seen (so do Cycles' passes, measured in 4.2.23 and 5.0.1: its Depth there is 1e10 as behind
        everything, its Normal, Object Index and Diffuse Direct 0)."""
        import gpu
        if self._depth is None:
            self.camera_prepass()
        if setup is not self.setup:
            raise WarpError("shade() takes the setup whose maps draw_maps() drew")
        t = time.perf_counter()
        read = self.read if read is None else check_read(read)
        blurred = shadow.eye_blur > 0
        world = bool(read & SURFACE)
        variant = shaders.ShadeVariant(
            map_count=len(setup.maps), light=light.type, pcf=shadow.pcf_kernel, mdsm=shadow.mdsm_depths,
            revectorize=shadow.revectorize,
            bias=shadow.bias_mode, regions=any(m.region is not None for m in setup.maps),
            ranges=any(m.view_depth_range is not None for m in setup.maps),
            blends=any(m.blend_band > 0 and m.view_depth_range is not None for m in setup.maps), blurred=blurred,
            shadow_alpha=not blurred and bool(read & {"shadow_mask", "shadow_raw"}),
            footprint="footprint_heatmap" in read, data=needs_data(read) or blurred, world=world,
            holdout=self.holds_out, unlit=self.leaves_unlit,
            linear_z=shaders.agreed(m.depth_row is not None for m in setup.maps),
            greater=shaders.agreed(m.depth_test == "GREATER" for m in setup.maps))
        ambient = tuple(float(c) for c in ambient)
        spec = [("color", "RGBA32F")]
        spec += [("footprint", "RGBA32F")] if variant.footprint else []
        spec += [("data", "RGBA32F")] if variant.data else []
        spec += [("world", "RGBA32F")] if world else []
        textures = {name: self.targets.texture(name, self.size, fmt) for name, fmt in spec}
        fb = self.targets.framebuffer(depth=self._depth, colors=tuple(textures.values()))
        block = shade_block(self.view, light, setup, shadow, albedo, self.origin, spot_blend, ambient, self.size)
        ubo = gpu.types.GPUUniformBuf(block.tobytes())
        w, h = self.size
        with fb.bind():
            # Two full-screen triangles on the far plane, tested against the pre-pass
            # depth: the background where nothing was drawn (no target is cleared),
            # the shading everywhere else, once per pixel.
            gpu.state.viewport_set(0, 0, w, h)
            gpu.state.depth_mask_set(False)
            gpu.state.depth_test_set("LESS_EQUAL")
            bg = shaders.background_shader(variant)
            bg.bind()
            # Under LIXEL_SHADOW_ALPHA the alpha holds the shadow, 0 here; finish() reads alpha - 1 as the
            # combined image's alpha - 1 where it is negative (-1: transparent).
            behind = (0.0, 0.0, 0.0, 0.0) if transparent else (*(ambient if background is None else background), 1.0)
            bg.uniform_float("u_background", (0.0, 0.0, 0.0, 0.0) if blurred else
                             (*behind[:3], behind[3] - 1.0) if variant.shadow_alpha else behind)
            compose.fullscreen_batch().draw(bg)
            sh = shaders.shade_shader(variant)
            sh.bind()
            sh.uniform_block("lixel", ubo)
            maps = self.keys or self.maps
            dummy = _dummy("RGBA32F" if self.keys else "DEPTH_COMPONENT32F")
            for i in range(shaders.MAX_MAPS):
                sh.uniform_sampler(f"u_map{i}", maps[i][0] if i < len(maps) else dummy)
            gpu.state.depth_test_set("GREATER")
            sh.uniform_sampler("u_surface", self._surface)
            compose.fullscreen_batch().draw(sh)
            gpu.state.depth_test_set("NONE")
        self._shaded = dict(textures=textures, variant=variant, ambient=ambient, albedo=float(albedo), behind=behind,
                            eye_blur=float(shadow.eye_blur))
        self._stage("shading", t, fb, color=True)

    def _blurred(self):
        """(blurred shadow, combined image) textures after the eye-space blur (made once)."""
        sh = self._shaded
        if "blurred" not in sh:
            size, targets, tex = self.size, self.targets, sh["textures"]
            d_near, _ = compose.reduce_range(targets, tex["data"], size, channel=3, above=0.0)
            if sh["variant"].holdout:   # held-out surfaces (their eye depth negated) count for the blur's radius,
                _, held = compose.reduce_range(targets, tex["data"], size, channel=3, below=0.0)
                d_near = min(d_near, -held)          # so a holdout changes no pixel beyond the blur's reach of it
            mask = compose.eye_blur_pass(targets, size, tex["data"], sh["eye_blur"],
                                         d_near if math.isfinite(d_near) else 1.0)
            compose.compose_pass(targets, size, tex["color"], mask, sh["ambient"], sh["albedo"], sh["behind"])
            sh["blurred"] = (mask, targets.texture("combined", size, "RGBA32F"))
        return sh["blurred"]

    def combined_texture(self):
        """The combined image as a GPU texture (RGBA32F, the frame's size), not read
        back: for drawing it (the viewport's picture-in-picture). Its alpha is
        the shadow when the frame reads the shadow back (``shade(read=...)``
        with "shadow_mask" or "shadow_raw"; see ``ShadeVariant.shadow_alpha``),
        1 otherwise. Valid until the targets are used by another frame."""
        if self._shaded is None:
            raise WarpError("combined_texture() needs shade() first")
        if self._shaded["variant"].blurred:
            return self._blurred()[1]
        return self._shaded["textures"]["color"]

    def _read_target(self, name: str, channels: int = 4) -> np.ndarray:
        tex = self._shaded["textures"][name]
        return compose.read_color(self.targets.framebuffer(colors=(tex,)), 0, self.size, channels)

    def finish(self, read=None) -> RenderResult:
        """Finish on the GPU (the eye-space blur and compose when the blur is on,
        the map preview when asked for) and read back the images named in
        ``read`` (see :class:`RenderResult`), each once."""
        read = self.read if read is None else check_read(read)
        if self._shaded is None:
            raise WarpError("finish() needs shade() first")
        sh = self._shaded
        variant = sh["variant"]
        data_images = {"shadow_raw", "covered", "eye_depth", "map_index", "texels_per_pixel"}
        missing = (read & SURFACE if not variant.world else set()) | \
            (read & (data_images - {"shadow_raw"}) if not variant.data else set()) | \
            (read & {"footprint_heatmap"} if not variant.footprint else set()) | \
            (read & {"shadow_mask", "shadow_raw"} if not (variant.shadow_alpha or variant.blurred) else set())
        if missing:
            raise WarpError(f"{', '.join(sorted(missing))}: made only when shade(read=...) asks for them")
        t = time.perf_counter()
        size, targets, tex = self.size, self.targets, sh["textures"]
        combined_fb = mask_fb = None
        if variant.blurred and read & {"combined", "shadow_mask"}:
            mask, combined = self._blurred()
            mask_fb = targets.framebuffer(colors=(mask,))
            combined_fb = targets.framebuffer(colors=(combined,))
        preview = None
        if "shadow_map_preview" in read:
            _, preview = compose.map_preview_pass(targets, "map_preview", size, self.maps[0][0], stretch=False)
        self._stage("compose", t, combined_fb or preview, color=True)

        t = time.perf_counter()
        out = RenderResult()
        if variant.shadow_alpha and read & {"combined", "shadow_mask", "shadow_raw"}:
            # One read of the colour target: its alpha is the shadow (>= 0), or where nothing is seen, the
            # combined image's alpha - 1 (see shade()); the combined image's alpha is 1 where a surface is.
            # Only a transparent film or a holdout has alphas below 0 (-1: a held-out surface's); an opaque film's
            # frame without holdouts skips two passes over the image.
            colour = self._read_target("color")
            alpha = colour[..., 3]
            if self._shaded["behind"][3] < 1.0 or variant.holdout:
                shadow = np.maximum(alpha, 0.0)
                np.minimum(alpha, 0.0, out=alpha)
                alpha += 1.0
            else:
                shadow = alpha.copy()   # not ascontiguousarray: a 1x1 alpha view is "contiguous" and would be shared
                alpha[...] = 1.0
            out.combined = colour if "combined" in read else None
            out.shadow_mask = shadow if "shadow_mask" in read else None
        else:
            if "combined" in read:
                out.combined = compose.read_color(combined_fb, 0, size) if combined_fb else self._read_target("color")
            if "shadow_mask" in read:
                out.shadow_mask = compose.read_color(mask_fb, 0, size, 1)
        if "footprint_heatmap" in read:
            out.footprint_heatmap = self._read_target("footprint")
        if preview is not None:
            out.shadow_map_preview = compose.read_color(preview, 0, size, 1)
        if variant.data and read & (data_images | SURFACE):
            data = self._read_target("data")
            covered = data[..., 3] > 0.0
            if "covered" in read:
                out.covered = covered
            if "shadow_raw" in read:
                shadow_raw = np.maximum(data[..., 0], 0.0)     # (-1 where the light does not light the surface)
                out.shadow_raw = np.where(covered, shadow_raw, 0.0).astype(np.float32)
            if "eye_depth" in read:
                out.eye_depth = np.where(covered, data[..., 3], np.inf).astype(np.float32)
            if "map_index" in read:
                out.map_index = np.where(covered, np.rint(data[..., 1]), -1).astype(np.int32)
            if "texels_per_pixel" in read:
                out.texels_per_pixel = np.where(covered, data[..., 2], 0.0).astype(np.float32)
            if read & SURFACE:
                world = self._read_target("world")
                out.world_position = np.where(covered[..., None], world[..., :3] + self.origin, np.nan)
                out.world_normal = np.where(covered[..., None], unpack_normals(world[..., 3]), np.nan)
        elif "shadow_raw" in read:
            out.shadow_raw = shadow
        if "shadow_maps" in read:
            out.shadow_maps = [compose.read_depth(f, tuple(int(v) for v in m.size))
                               for (_, f), m in zip(self.maps, self.setup.maps)]
        if "mdsm_keys" in read:
            out.mdsm_keys = [compose.read_color(f, 0, tuple(int(v) for v in m.size))
                             for (_, f), m in zip(self.keys, self.setup.maps)]
        self.timings["readback"] = time.perf_counter() - t

        s, c = self.scene, self.counts
        c.uploads = s.batches.uploads - self._before[0]
        c.uploaded_triangles = s.batches.uploaded_triangles - self._before[1]
        c.matrix_uploads = s.matrix_uploads - self._before[2]
        c.list_uploads = s.list_uploads - self._before[3]
        c.target_allocations = self.targets.allocations - self._before[4]
        per_map = [map_bytes([m.size]) for m in self.setup.maps]
        w, h = size
        out.memory = RenderMemory(
            per_map_bytes=per_map,
            mdsm_bytes_per_layer=list(per_map) if self.keys else [],
            mdsm_texture_bytes=[map_bytes([m.size], mdsm=True) - b for m, b in zip(self.setup.maps, per_map)]
            if self.keys else [],
            render_target_bytes=w * h * (4 + 16 + 16 * (variant.footprint + variant.data + variant.world)),
        )
        out.timings = dict(self.timings)
        out.counts = c
        self.targets.trim()
        return out


def needs_data(read) -> bool:
    """Whether the images in ``read`` need the shading pass's data target."""
    return bool(set(read) & ({"covered", "eye_depth", "map_index", "texels_per_pixel"} | SURFACE))


@one_blas_thread()
def render_shadows(view: View, light: Light, setup: ShadowSetup, geometry, settings=None,
                   resolution: Optional[tuple[int, int]] = None, *, body=None,
                   scene: Optional[GPUScene] = None, targets: Optional[TargetPool] = None,
                   ambient=DEFAULT_AMBIENT, albedo: float = DEFAULT_ALBEDO,
                   spot_blend: float = 0.0, read=ANALYSIS, background=None, lit=None, blocks=None,
                   transparent: bool = False) -> RenderResult:
    """Render ``geometry`` from ``view`` with the shadow maps of ``setup``: a
    whole :class:`ShadowFrame` in one call.

    Needs a GPU context (``addon.gpu.context.ensure_gpu_context()``; inside a
    RenderEngine with ``bl_use_gpu_context`` it already exists).

    ``geometry``: an ``addon.scene.geometry.SceneGeometry`` (from
    ``GeometryCache.update(depsgraph)`` or ``SceneGeometry.from_arrays``).
    ``settings``: ``LixelSettings`` or ``ShadowSettings`` (bias, PCF, MDSM, blur);
    default ``LixelSettings()``. ``resolution``: (w, h), default
    ``view.resolution``. ``body``: the intersection body if already computed
    (it culls casters); computed from the geometry's bounds otherwise.
    ``scene``/``targets``: see :class:`ShadowFrame`.
    ``ambient``: world colour; ``background``: seen where no surface is (default ``ambient``); ``albedo``: surface
    grey; ``spot_blend``: a spot
    light's Blender ``spot_blend`` (softness of the cone edge, 0 = hard).
    ``read``: the :class:`RenderResult` images to read back (default
    ``result.ANALYSIS``; ``result.EVERYTHING`` adds the world position, the
    maps and the map preview). ``lit``/``blocks``: the light's Light and Shadow Linking (see :class:`ShadowFrame`).
    ``transparent``: Film Transparent (see :meth:`ShadowFrame.shade`).
    """
    shadow = _shadow_settings(settings)
    read = check_read(read)
    if not setup.maps:
        raise WarpError("the shadow setup has no maps")
    if len(setup.maps) > shaders.MAX_MAPS:
        raise WarpError(f"the shadow setup has {len(setup.maps)} maps; Lixel's shader takes at most {shaders.MAX_MAPS}")
    frame = ShadowFrame(geometry, view, resolution, read=read, scene=scene, targets=targets, lit=lit, blocks=blocks)
    if body is None:
        try:
            body = intersection_body(view, light, geometry.instances.bounds)
        except EmptyBodyError as exc:
            log.info("Lixel: %s; nothing casts a visible shadow", exc)
            body = None
    frame.camera_prepass()
    frame.draw_maps(setup, shadow, body)
    frame.shade(light, setup, shadow, albedo, spot_blend, ambient, background=background, transparent=transparent)
    return frame.finish()
