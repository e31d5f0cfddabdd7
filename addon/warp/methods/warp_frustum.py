"""The light-space perspective warp P shared by ``lispsm``, ``gmnpr`` and ``glpr``: Wimmer et al.'s LiSPSM
made robust by Scherzer §4.4 (Fig. 9, Eq. 1-3), the three differing only in their λ rule (:mod:`..aliasing`).
Its derivation, the point-light transfer and the fades: docs/papers.md, "The warp core's derivations"."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..aliasing import (folded, lambda_glpr, lambda_gmnpr, lambda_least_on_screen, lambda_no_worse_on_average,
                        lambda_no_worse_than_uniform, lispsm_inverse_n_opt)
from ..body import IntersectionBody
from ..diagnostics import Diagnostics
from ..fit import fit_runs, fit_to_unit_cube, window_matrices
from ..frame import PARALLEL_BLEND, LightFrame, body_light_angles, light_frames, pyramid_sections
from ..geometry import finite_clip_volume_corners, homogeneous, point_runs, transform_h_runs
from ..linear_depth import frame_depth_row
from ..partition.receivers import edge_samples, filter_losses
from ..types import Light, ShadowMap, ShadowSetup, View, WarpError, WarpOptions
from .common import frame_maps, near_plane_notes

TURNS = np.array([[[math.cos(a), -math.sin(a), 0, 0], [math.sin(a), math.cos(a), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
                  for a in np.radians(np.arange(-45.0, 45.0, 2.5))])
"""The turns of a map's x, y about its depth axis that ``edge_turned`` weighs against the shadow edges (every 2.5°)."""
FADE_START = 2.0
FADE_END = 4.0
"""Point-light frames: the warp fades out (linearly in μ) as the eye's image moves
from FADE_START to FADE_END half-diagonals of B's image away from its centre."""


@dataclass
class WarpContext:
    """What every frame of one setup shares: the eye-depth range and the view."""

    z_n: float
    z_f: float
    visible: Optional[tuple[np.ndarray, np.ndarray, np.ndarray]] = None
    """The visible surface as weighted world points (``VisibleRegion.samples``) and their eye depths, when B was
    focused."""
    edges: Optional[np.ndarray] = None
    """Per visible point, the shadow-edge samples it stands for (``VisibleRegion.edge_weights``; None: unknown)."""
    phi: float = 0.0
    """GMNPR's φ (half the field of view towards the light), for the λ guard's model."""
    guard: bool = False
    """Whether the rule's λ is guarded (``guard_lambda``, as ``WarpOptions.lambda_guard`` says)."""


@dataclass
class LightAtEye:
    """The light as the eye sees it, in world space: what every frame of one setup shares."""

    ell: np.ndarray        # the light ray at the eye (unit): a sun's direction, or from the light through the eye
    dist: float            # point lights: the eye's distance from the light (0 for a sun)
    gamma: float           # angle between the view direction and ell
    vector: np.ndarray     # the world vector whose image is V_P: the view direction or the middle vector
    s: float               # sin of the angle between ``vector`` and ell (the weight of the blend into +y)
    v_p: Optional[np.ndarray] = None  # point lights: the view direction perpendicular to ell (None if parallel)
    body_extent: float = 0.0          # point lights: all of B's extent along v_p


@dataclass
class WarpAxis:
    """A warp's depth axis in a light frame (``to_light``: world -> light space, rays along z): V_P as the unit
    2-vector ``a`` in the image plane and B's part along it, ``h_min`` over ``extent`` D (docs/papers.md)."""

    to_light: np.ndarray
    a: tuple
    h_min: float
    extent: float


@dataclass
class FrameGeometry(WarpAxis):
    """One frame's warp geometry, in that frame's (divided) light space."""

    eye: tuple             # the eye in light space
    extent_world: float    # the frame's part of B along the world V_P
    body_extent_world: float  # all of B along the world V_P (the paper's P_f - P_n)
    gamma: float
    v_p_world: Optional[np.ndarray]
    fade: float

    @property
    def b(self) -> tuple:
        """P's lateral axis: V_P turned by -90° in the image plane."""
        return self.a[1], -self.a[0]


def light_at_eye(view: View, light: Light, options: WarpOptions, body: IntersectionBody,
                 middle: Optional[np.ndarray]) -> tuple[Optional[LightAtEye], str]:
    """What every frame shares in world space, or (None, why): an orthographic camera, no light ray through the eye."""
    if view.orthographic:
        return None, "orthographic camera: no perspective aliasing to redistribute"
    d = view.direction
    if light.is_directional:
        ell, dist = light.direction, 0.0
    else:
        to_eye = view.position - light.position
        dist = math.sqrt(to_eye @ to_eye)
        if dist <= 1e-9 * body.scale:
            return None, "the eye is at the light: the light ray through the eye is undefined"
        ell = to_eye / dist
    vector = middle if options.middle_vector else d
    s = _sin_between(vector, ell) if (options.middle_vector or not light.is_directional) else 1.0
    cos_gamma = min(max(float(d @ ell), -1.0), 1.0)
    at = LightAtEye(ell, dist, math.acos(cos_gamma), vector, s)
    if not light.is_directional:
        across = d - cos_gamma * ell
        length = math.sqrt(across @ across)
        if length > 0:
            at.v_p = across / length
            at.body_extent = float(np.ptp(body.vertices @ at.v_p))
    return at, ""


def _sin_between(v: np.ndarray, ell: np.ndarray) -> float:
    """sin of the angle between ``v`` and the unit ``ell`` (0 for a zero ``v``)."""
    u = _unit_or_zero(v)
    across = u - (u @ ell) * ell
    return math.sqrt(across @ across)


def eye_depth_range(view: View, body: IntersectionBody, options: WarpOptions, diag: Diagnostics,
                    at: Optional[LightAtEye] = None) -> WarpContext:
    """z_n and z_n + Δz for Eq. 1 / GMNPR's (n, f): eye depths (docs/papers.md); given ``at``, GMNPR's φ towards it."""
    depths = view.eye_depth(body.visible_vertices)
    nearest, farthest = float(depths.min()), float(depths.max())
    if options.delta_z == "visible":
        if options.visible_depth_range is None:
            diag.fallback("delta_z", "'visible' was asked for but no visible_depth_range was given; Δz from B")
        else:
            nearest, farthest = (float(v) for v in options.visible_depth_range)
    z_n = max(view.near, nearest)
    z_f = max(min(view.far, farthest), z_n)
    phi = 0.0 if at is None else half_fov_towards(view, at.ell)
    if body.visible is None:
        return WarpContext(z_n, z_f, phi=phi)
    visible = body.visible.samples(view)
    return WarpContext(z_n, z_f, (*visible, view.eye_depth(visible[0])), body.visible.edge_weights(), phi)


def half_fov_towards(view: View, light_dir) -> float:
    """GMNPR's φ: the angle from the view axis to the view frustum's side towards the (folded) light direction's
    projection onto the image, lens shift included."""
    axes = view.camera_to_world[:3, :3]
    cx, cy, cz = ((np.asarray(light_dir, dtype=np.float64) @ axes) / np.sqrt(np.einsum("ij,ij->j", axes, axes))).tolist()
    if cz > 0:                           # fold: the light line's half that points along the view (-Z)
        cx, cy = -cx, -cy
    (p00, _, p02, _), (_, p11, p12, _) = view.projection[:2].tolist()
    sides = [(-1.0 + p02) / p00, (1.0 + p02) / p00, (-1.0 + p12) / p11, (1.0 + p12) / p11]
    length = math.hypot(cx, cy)
    if length < 1e-300:
        return math.atan(max(min(map(abs, sides)), 1e-9))
    u = (cx / length, cy / length)
    reach = [side / u[axis] for axis, side in zip((0, 0, 1, 1), sides) if side * u[axis] > 0]
    return math.atan(max(min(reach, default=math.inf), 1e-9))


# ---------------------------------------------------------------------------
# Each frame's warp: V_P in its image, B's extent along it, λ, and P.
# ---------------------------------------------------------------------------

def frame_geometries(at: LightAtEye, frames: list, to_light: np.ndarray, b_in_light: np.ndarray, starts: list,
                     run: np.ndarray, view: View, options: WarpOptions, body: IntersectionBody) -> list:
    """Each frame's warp geometry (V_P, eye, fade and B's extent along V_P), or why its map stays uniform."""
    images = (to_light @ np.array([view.position.tolist() + [1.0], at.vector.tolist() + [0.0]]).T).transpose(0, 2, 1).tolist()
    boxes = [None] * len(frames)                       # (a point light frame's points, (lo, hi) in light space)
    if not frames[0].directional:
        boxes = zip(np.minimum.reduceat(b_in_light, starts).tolist(), np.maximum.reduceat(b_in_light, starts).tolist())
    axes = [frame_axes(at, f, eye_h, vector_h, box, options) for f, (eye_h, vector_h), box in zip(frames, images, boxes)]
    a = np.array([ax[0] if not isinstance(ax, str) else (0.0, 1.0) for ax in axes])
    h = np.einsum("ij,ij->i", b_in_light[:, :2], a[run])                # along each frame's V_P
    h_min = np.minimum.reduceat(h, starts).tolist()
    extent = (np.maximum.reduceat(h, starts) - h_min).tolist()
    if frames[0].directional:                                         # V_P in the world, the frame's own
        v_p = a[:, :1] * to_light[:, 0, :3] + a[:, 1:] * to_light[:, 1, :3]
        along = body.vertices @ v_p.T
        extent_world, body_extent = extent, np.ptp(along, axis=0).tolist()
    else:                                                             # perpendicular to the light ray at the eye
        v_p, body_extent, extent_world = [at.v_p] * len(frames), [at.body_extent] * len(frames), [0.0] * len(frames)
        if at.v_p is not None:
            along = np.concatenate([f.points for f in frames]) @ at.v_p
            extent_world = (np.maximum.reduceat(along, starts) - np.minimum.reduceat(along, starts)).tolist()
    return [ax if isinstance(ax, str) else
            FrameGeometry(frames[k].to_light, ax[0], h_min[k], extent[k], ax[1], extent_world[k], body_extent[k],
                          at.gamma, v_p[k], ax[2])
            for k, ax in enumerate(axes)]


def frame_axes(at: LightAtEye, frame: LightFrame, eye_h: list, vector_h: list, box, options: WarpOptions):
    """A frame's warp axes in its light space (V_P as a unit 2-vector, the eye, the fade), or why there are none."""
    x, y, z, w = eye_h
    if frame.directional:             # a sun frame's +y is Eq. 3's V_P (blended near parallel, frame.image_up)
        v_p = _image_direction(vector_h[:2], at.s) if options.middle_vector else (0.0, 1.0)
        return v_p, (x / w, y / w, z / w), 1.0
    if not w > 1e-12 * at.dist:
        return "the eye is behind this frame's light plane: no warp in its post-perspective space"
    vx, vy, _, vw = vector_h
    image = ((vx * w - x * vw) / (w * w), (vy * w - y * vw) / (w * w))     # d(x/w, y/w) along the vector, at the eye
    eye, fade = _eye_and_fade((x / w, y / w, z / w), box)
    return _turned(_image_direction(image, at.s), fade), eye, fade


def _eye_and_fade(eye: tuple, box) -> tuple[tuple, float]:
    """A point light frame's fade (``FADE_START``..``FADE_END`` half-diagonals of B's image from its centre) and
    the eye kept within a box holding the fade region."""
    (xlo, ylo, zlo), (xhi, yhi, zhi) = box
    cx, cy = (xlo + xhi) / 2, (ylo + yhi) / 2
    half = max(math.hypot(xhi - xlo, yhi - ylo) / 2, 1e-300)
    ex, ey, ez = eye
    fade = min(max((FADE_END - math.hypot(ex - cx, ey - cy) / half) / (FADE_END - FADE_START), 0.0), 1.0)
    reach, depth = FADE_END * half, FADE_END * (zhi - zlo)
    return (min(max(ex, cx - reach), cx + reach), min(max(ey, cy - reach), cy + reach),
            min(max(ez, zlo - depth), zhi + depth)), fade


def _image_direction(v, s: float) -> tuple[float, float]:
    """The unit image-plane direction along ``v`` (sine ``s`` to the light), blended into the frame's +y as s falls
    below PARALLEL_BLEND (+y for a zero or infinite ``v``)."""
    length = math.hypot(*v)
    vx, vy = (v[0] / length, v[1] / length) if length > 0 and math.isfinite(length) else (0.0, 1.0)
    bx, by = s * vx, s * vy + max(0.0, PARALLEL_BLEND - s)
    length = math.hypot(bx, by)
    return (bx / length, by / length) if length > 1e-12 else (0.0, 1.0)


def _turned(a: tuple, fade: float) -> tuple[float, float]:
    """A fading warp turns its axes back towards the frame's +y with it, so
    that at fade = 0 the map is exactly the frame's uniform map."""
    if fade >= 1.0:
        return a
    turn = fade * math.atan2(a[0], a[1])
    return math.sin(turn), math.cos(turn)


def warp_matrix(g: FrameGeometry, mu: float) -> np.ndarray:
    """P acting on the frame's homogeneous light space [X, Y, Z, W] (docs/papers.md)."""
    (a0, a1), (b0, b1), (ex, ey, ez) = g.a, g.b, g.eye
    to_delta = 1.0 / g.extent if g.extent > 0 else 0.0
    delta = [a0 * to_delta, a1 * to_delta, 0.0, -g.h_min * to_delta]           # δ = (h - h_min) / D
    return np.array([[b0, b1, 0.0, -(ex * b0 + ey * b1)],                      # x' = q - q_eye·W
                     delta,                                                    # y' = δ·W
                     [0.0, 0.0, 1.0, -ez],                                     # z' = Z - z_eye·W
                     [mu * c for c in delta[:3]] + [mu * delta[3] + 1.0]])     # w' = (1 + μ·δ)·W


LambdaRule = Callable[[FrameGeometry, WarpContext, float, WarpOptions], float]
"""(geometry, eye-depth range, φ, options) -> λ (math.inf = uniform); φ is None for lispsm."""


def rule_lispsm(g: FrameGeometry, ctx: WarpContext, phi: Optional[float], options: WarpOptions) -> float:
    """λ = n_opt / D with n_opt from Scherzer Eq. 1."""
    k = lispsm_inverse_n_opt(ctx.z_n, ctx.z_f - ctx.z_n, g.gamma)
    return math.inf if k == 0.0 or g.body_extent_world <= 0.0 else 1.0 / (k * g.body_extent_world)


def _forced(options: WarpOptions) -> Optional[float]:
    if options.lam is not None and not float(options.lam) > 0:
        raise WarpError(f"the forced λ must be positive (got {options.lam}); leave it unset for Eq. 8")
    return None if options.lam is None else float(options.lam)


def rule_gmnpr(g: FrameGeometry, ctx: WarpContext, phi: float, options: WarpOptions) -> float:
    """GMNPR Eq. 8 (or the forced ``options.lam``)."""
    return _forced(options) or lambda_gmnpr(folded(g.gamma), ctx.z_n, ctx.z_f, phi)


def rule_glpr(g: FrameGeometry, ctx: WarpContext, phi: float, options: WarpOptions) -> float:
    """GLPR, F(z) ~ z (or the forced ``options.lam``)."""
    return _forced(options) or lambda_glpr(folded(g.gamma), ctx.z_n, ctx.z_f, phi)


_GUARD_BOUNDS: dict = {}
"""``guard_lambda``'s two costly bounds of the last frames, by their inputs' bytes."""


def guard_lambda(lam: float, gamma: float, axis: WarpAxis, ctx: WarpContext, scale: float = 1.0,
                 body_h: Optional[np.ndarray] = None) -> tuple[float, Optional[str]]:
    """``lam`` raised to the least λ at which the warp is no worse than the uniform map (docs/papers.md, "The λ
    guard"), at its worst over [z_n, z_f] and over the visible pixels along ``axis`` (and across it, given B's
    homogeneous vertices ``body_h`` and ``axis`` a FrameGeometry), and to the λ whose texels are least on screen
    over the visible pixels, or over the shadow edges seen where known (``ctx.edges``): (λ, why raised or "")."""
    theta = folded(gamma)
    bounds = {f"its worst aliasing over the visible depths (far {ctx.z_f / ctx.z_n:.4g}x near) would be worse than the "
              f"uniform map's": lambda_no_worse_than_uniform(theta, ctx.z_n, ctx.z_f, ctx.phi)}
    if ctx.visible is not None and axis.extent > 0 and scale > 0:
        points, weights, depth = ctx.visible
        delta = _along_across(homogeneous(points), axis)[0]
        body = None if body_h is None else _along_across(body_h, axis, float(np.dot(axis.eye[:2], axis.b)))
        edges = ctx.edges if ctx.edges is not None and ctx.edges.sum() > 0 else None     # (part 7: where errors can be)
        # (once per input: a cascade split's lispsm and gmnpr ask for the same)
        key = tuple(a if a is None else (np.shape(a), np.asarray(a, dtype=np.float64).tobytes())
                    for a in (delta, weights, depth, body, edges))
        if (made := _GUARD_BOUNDS.get(key)) is None:
            if len(_GUARD_BOUNDS) >= 16:                     # (a point light's 6 faces and more)
                _GUARD_BOUNDS.clear()
            made = _GUARD_BOUNDS[key] = (lambda_no_worse_on_average(delta, weights, body), lambda_least_on_screen(
                delta, weights if edges is None else edges, depth, body))
        bounds["its aliasing over the visible pixels (its texels' side along V_P or their longer side, L2 over them) "
               "would be worse than the uniform map's"] = made[0] * scale
        bounds["its texels would be larger on screen, on average over the visible "
               + ("pixels" if edges is None else "shadow edges")] = made[1] * scale
    why, guard = max(bounds.items(), key=lambda item: item[1])
    if not guard > lam:
        return lam, None
    return guard, (f"λ raised from {lam:.4g} to {guard:.4g}" + (" (the uniform map)" if guard == math.inf else "")
                   + f": below it {why} (θ = {math.degrees(theta):.1f}°, φ = {math.degrees(ctx.phi):.1f}°)")


def _along_across(points_h: np.ndarray, axis: WarpAxis, q_0: float = 0.0) -> np.ndarray:
    """(2, N): homogeneous world points' δ = (h - h_min)/D along ``axis``'s V_P and (q - ``q_0``)/D across it."""
    h = points_h @ axis.to_light.T
    x, y = h[:, 0] / h[:, 3], h[:, 1] / h[:, 3]
    return np.array([x * axis.a[0] + y * axis.a[1] - axis.h_min, x * axis.a[1] - y * axis.a[0] - q_0]) / axis.extent


def map_lambda(matrix: np.ndarray, frame: LightFrame) -> tuple[Optional[WarpAxis], float]:
    """The warp of any light map in ``frame``'s terms (GMNPR §3's λ read from the map): its axis V_P and
    λ = (h_min - h_0)/D (None and ∞ for a map affine there)."""
    w_row = (matrix @ np.linalg.inv(frame.to_light))[3].tolist()
    length = math.hypot(w_row[0], w_row[1])
    light = frame.points_h @ frame.to_light.T
    image = light[:, :2] / light[:, 3:]
    if not length > 1e-12 * (abs(w_row[3]) + length * float(np.abs(image).max())):
        return None, math.inf
    a = (w_row[0] / length, w_row[1] / length)
    h = image @ a
    h_min, extent = float(h.min()), float(h.max() - h.min())
    if not extent > 0:
        return None, math.inf
    return WarpAxis(frame.to_light, a, h_min, extent), (h_min + w_row[3] / length) / extent


def edge_turned(fitted: np.ndarray, points: np.ndarray, body: IntersectionBody,
                to_world: np.ndarray = np.eye(4)) -> np.ndarray:
    """``fitted`` (``points``' coordinates to light clip; ``to_world``: world to them) turned about its depth axis by
    the one of ``TURNS`` that, fitted again to the points (§4), has the least ``filter_losses`` (texels wide across
    the first look's shadow edges, or along them) there, if any (docs/papers.md, "Texel axes off the shadow edges")."""
    if not len(edges := edge_samples(body.visible)):
        return fitted
    turns = fit_to_unit_cube(TURNS @ fitted, points)
    return turns[int(np.argmin(filter_losses([ShadowSetup([ShadowMap(m, (2, 2))], None) for m in turns @ to_world],
                                             (None,) * 4 + (edges,))))]


def _unit_or_zero(v: np.ndarray) -> np.ndarray:
    length = math.sqrt(v @ v)
    return v / length if length > 0 else np.zeros(3)


def _finite_or_none(x: float) -> Optional[float]:
    return float(x) if math.isfinite(x) else None


@dataclass
class FrameWarp:
    """One frame's warped map, or the reason it is uniform."""

    frame: LightFrame
    notes: list                            # fallbacks (what, reason), in order
    geo: Optional[FrameGeometry] = None    # None: the frame's map is uniform
    lam: float = math.inf
    p_n: float = math.inf
    lam_frame: float = math.inf
    mu: float = 0.0
    matrix: Optional[np.ndarray] = None    # the fitted map (the frame's uniform map when geo is None)
    held: Optional[np.ndarray] = None      # after ray closure: the vertices of B ∩ window the map holds


def frame_warps(frames: list, view: View, at: Optional[LightAtEye], reason: str, rule: LambdaRule,
                ctx: WarpContext, phi: Optional[float], options: WarpOptions, body: IntersectionBody) -> list:
    """Every frame's warp (``at`` None: all uniform for ``reason``) and the unit-cube fit of every map at once."""
    points_h, starts, run = point_runs([f.points for f in frames])
    to_light = np.array([f.to_light for f in frames])
    b_in_light_h = transform_h_runs(to_light, points_h, run)
    b_in_light = b_in_light_h[:, :3] / b_in_light_h[:, 3:]
    geometries = frame_geometries(at, frames, to_light, b_in_light, starts, run, view, options, body) if at is not None \
        else [reason] * len(frames)
    warps, warp = [], np.tile(np.eye(4), (len(frames), 1, 1))      # uniform where the warp is undefined
    for k, (frame, geo) in enumerate(zip(frames, geometries)):
        w = FrameWarp(frame, near_plane_notes([frame]))
        warps.append(w)
        if isinstance(geo, str):
            w.notes.append((f"{frame.role}: uniform", geo))
            continue
        lam, guarded = rule(geo, ctx, phi, options), None
        if ctx.guard and options.lam is None:
            # (the rules' λ is in units of all of B's extent along V_P, this frame's in its part's; across V_P too for
            # a sun's frame only: on point-light faces it left warped faces worse than unwarped, tests/warp/test_cascade)
            scale = geo.extent_world / geo.body_extent_world if geo.body_extent_world > 0 else 0.0
            lam, guarded = guard_lambda(lam, geo.gamma, geo, ctx, scale, frame.points_h if frame.directional else None)
        _warp_strength(w, geo, lam, guarded)
        warp[k] = warp_matrix(geo, w.mu)
    for w, matrix in zip(warps, fit_runs(warp, b_in_light_h, starts, run) @ to_light):
        w.matrix = matrix
    return warps


def _warp_strength(w: FrameWarp, geo: FrameGeometry, lam: float, guarded: Optional[str]) -> None:
    """The frame's λ, P_n (world units), its own λ and μ, and their notes (``guarded``: why the guard raised λ)."""
    role = w.frame.role
    if guarded:
        w.notes.append((f"{role}: λ guard", guarded))
    p_n = lam * geo.body_extent_world if math.isfinite(lam) else math.inf       # P_n in world units
    lam_frame = p_n / geo.extent_world if geo.extent_world > 0 else math.inf    # λ for this frame's part of B
    mu = 0.0 if not math.isfinite(lam_frame) else geo.fade / lam_frame
    if geo.fade < 1.0:
        w.notes.append((f"{role}: warp faded", f"the eye's image is far outside B's image in this frame; warp "
                                               f"strength x{geo.fade:.3g}" + (" (uniform)" if geo.fade == 0 else "")))
    if mu == 0.0 and geo.fade > 0.0 and not guarded:     # (a guard that made it uniform says why itself)
        w.notes.append((f"{role}: uniform limit", "light parallel to the view direction (γ = 0): "
                                                 "n_opt = ∞, the warp is the uniform map"))
    w.geo, w.lam, w.p_n, w.lam_frame, w.mu = geo, lam, p_n, lam_frame, mu


def warped_setup(name: str, rule: LambdaRule, view: View, light: Light, body: IntersectionBody,
                 options: WarpOptions) -> ShadowSetup:
    """The maps of one warp method: one warped map per light frame, ray-closed over B when several (``ray_closed``)."""
    diag = Diagnostics(name, body_vertices=body.vertices)
    frames = light_frames(view, light, body, options)
    middle = body.volume_centroid - view.position          # B's middle vector (Scherzer §4.4)
    at, reason = light_at_eye(view, light, options, body, middle)
    ctx = eye_depth_range(view, body, options, diag, at)
    ctx.guard = options.lambda_guard in ("all", name)
    diag.extra.update(z_n=ctx.z_n, delta_z=ctx.z_f - ctx.z_n, frames=[f.role for f in frames],
                      middle_vector=_unit_or_zero(middle))
    # GMNPR's φ: gmnpr and glpr use and report it, LiSPSM's Eq. 1 has no φ (the λ guard's model has).
    phi = ctx.phi if at is not None and name != "lispsm" else None
    warps = frame_warps(frames, view, at, reason, rule, ctx, phi, options, body)
    warped = [w for w in warps if w.geo is not None]
    if len(frames) > 1 and warped:
        for w, (matrix, closure, held) in zip(warped, ray_closed([w.matrix for w in warped], body, light.position)):
            w.matrix, w.held = matrix, held
            if matrix is None:
                w.geo, w.matrix = None, frame_maps([w.frame], options.shadow_map_size)[0].matrix
                w.notes.append((f"{w.frame.role}: uniform", closure))
    if len(frames) == 1 and warps[0].geo is not None:      # (a sun, a spot or point light with one map: PSM's turn)
        warps[0].matrix = edge_turned(warps[0].matrix, frames[0].points, body)
    maps: list[ShadowMap] = []
    for w in warps:
        diag.fallbacks += w.notes
        held = None if w.held is None else np.concatenate([w.frame.points, w.held])
        depth_row = frame_depth_row(w.frame, held) if options.linear_z else None
        maps.append(ShadowMap(w.matrix, options.shadow_map_size, "LESS", w.frame.role, depth_row=depth_row))
    first = next((w for w in warps if w.geo is not None), None)
    if first is None:                    # no warped map: the angles to the light's axis, as for a uniform map
        diag.theta, diag.gamma = body_light_angles(view, light, body)
    else:
        report_warp(diag, name, first, phi)
    return ShadowSetup(maps, diag)


def report_warp(diag: Diagnostics, name: str, w: FrameWarp, phi: Optional[float]) -> None:
    """A warp method's diagnostics from its first warped map: θ, γ, n_opt and λ (``name``'s in the fields), μ, P's
    corners, V_P and P's centre."""
    geo = w.geo
    diag.theta, diag.gamma = folded(geo.gamma), geo.gamma
    if name == "lispsm":
        diag.n_opt = _finite_or_none(w.p_n)
        diag.extra["lambda"] = _finite_or_none(w.lam)
    else:
        diag.lam = _finite_or_none(w.lam)
        diag.extra.update(n_opt=_finite_or_none(w.p_n), phi=phi)
    diag.warp_frustum_corners = finite_clip_volume_corners(w.matrix)
    diag.extra.update(warp_strength_mu=w.mu, v_p=geo.v_p_world if geo.v_p_world is not None else np.zeros(3),
                      projection_centre=projection_centre(w.frame, geo, w.lam_frame))


def ray_closed(matrices, body: IntersectionBody, light_position) -> list:
    """A point light's cube-face maps made ray-closed over B: each map's depth range widened to B ∩ its window
    (``frame.pyramid_sections``). Per map: the re-fitted matrix, a note and the vertices of B ∩ window; or None and
    why (that part of B touches the light)."""
    m = np.asarray(matrices, dtype=np.float64)                   # (k, 4, 4)
    rows = m[:, :, :3]                     # on directions from the light (every row but z vanishes at the light)
    # The window's sides x = ±w, y = ±w, as outward normals x - w, -x - w, y - w, -y - w.
    sides = _WINDOW_SIDES @ rows                                 # (k, 4, 3)
    sides /= np.sqrt((sides * sides).sum(axis=2))[..., None]
    # Its corner rays: the directions the map sends to (x, y, w) = (±1, ±1, 1), so w > 0 on them.
    rays = (np.linalg.inv(rows[:, _XYW]) @ _WINDOW_CORNERS).transpose(0, 2, 1)
    held, run = pyramid_sections(body.polytope_from(light_position), sides, rays)
    held += light_position                                       # B ∩ window of every map, one after another
    closed = [(matrix, "", None) for matrix in m]
    if not len(run):
        return closed
    h = transform_h_runs(m, homogeneous(held), run)
    count = np.bincount(run, minlength=len(m))
    meets = np.flatnonzero(count)                                # the maps whose window meets B
    starts = np.cumsum(count)[meets] - count[meets]
    w = h[:, 3]
    ndc = h[:, :3] / np.where(w > 0, w, 1.0)[:, None]            # (w > 0 throughout where it does not reach)
    lo, hi = np.minimum.reduceat(ndc, starts), np.maximum.reduceat(ndc, starts)
    w_lo, w_hi = np.minimum.reduceat(w, starts), np.maximum.reduceat(w, starts)
    refitted = window_matrices(lo.tolist(), hi.tolist()) @ m[meets]
    for k, (i, start) in enumerate(zip(meets, starts)):
        mine = held[start:start + count[i]]
        if w_lo[k] <= 1e-9 * max(w_hi[k], -w_lo[k]):             # w = 0: the window's part of B reaches the light
            closed[i] = (None, "the warped map's window reaches the light itself; a uniform face map is ray-closed",
                         None)
        elif lo[k].min() >= -1.0 - 1e-9 and hi[k].max() <= 1.0 + 1e-9:     # the map already holds B ∩ window
            closed[i] = (m[i], "", mine)
        else:
            closed[i] = (refitted[k], "depth widened to B within the map's window", mine)
    return closed


_WINDOW_SIDES = np.array([[1.0, 0.0, 0.0, -1.0], [-1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0], [0.0, -1.0, 0.0, -1.0]])
"""The window's sides x - w, -x - w, y - w, -y - w as combinations of a map's rows x, y, z, w."""
_XYW = [0, 1, 3]
_WINDOW_CORNERS = np.array([[-1.0, -1.0, 1.0, 1.0], [-1.0, 1.0, -1.0, 1.0], [1.0, 1.0, 1.0, 1.0]])
"""The window's 4 corners (columns) in a map's (x, y, w): its corner rays are the directions sent there."""


def projection_centre(frame: LightFrame, g: FrameGeometry, lam: float) -> Optional[np.ndarray]:
    """P's centre in world space: P_n = λ·D behind B's near side along V_P, at the
    eye's lateral position and height (None when λ = ∞)."""
    if not math.isfinite(lam):
        return None
    h_c = g.h_min - lam * g.extent
    (a0, a1), (b0, b1), (ex, ey, ez) = g.a, g.b, g.eye
    q_e = ex * b0 + ey * b1
    x, y, z, w = np.linalg.solve(frame.to_light, [q_e * b0 + h_c * a0, q_e * b1 + h_c * a1, ez, 1.0]).tolist()
    if not abs(w) > 1e-300:
        return None
    centre = (x / w, y / w, z / w)
    return np.array(centre) if all(math.isfinite(c) for c in centre) else None
