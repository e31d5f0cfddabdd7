"""Plain data in and out of the warp core (numpy float64, no bpy): :class:`View`, :class:`Light`,
:class:`SceneBounds`, :class:`WarpOptions` in; :class:`ShadowSetup` (:class:`ShadowMap` list, diagnostics) out."""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Optional

import numpy as np

from .diagnostics import Diagnostics
from .geometry import normalize, perspective_matrix, transform_h, transform_points, UNIT_CUBE_CORNERS


class WarpError(ValueError):
    """A configuration the warp core cannot handle; the message says what and why."""


class EmptyBodyError(WarpError):
    """The intersection body B is empty: nothing visible can be shadowed."""


MAX_CLIP_RATIO = float(2 ** 24)
"""Largest clip end / start of a perspective camera: beyond it 32-bit float depth (the GPU's depth buffers and the
projection uploaded to it) cannot tell the clip range's ends apart near the far plane (orthographic depth is linear)."""


def clip_range_beyond_depth(near: float, far: float, orthographic: bool, length=lambda v: f"{v:g}") -> str:
    """Why a camera clipping from ``near`` to ``far`` (as ``length`` writes them) is past :data:`MAX_CLIP_RATIO` ("" if not)."""
    return "" if orthographic or far / near <= MAX_CLIP_RATIO else (f"clips from {length(near)} to {length(far)}, "
            f"a range of 1:{far / near:.3g}, beyond what 32-bit float depth resolves (1:{MAX_CLIP_RATIO:,.0f})")


def _mat4(m, name) -> np.ndarray:
    a = np.asarray(m, dtype=np.float64)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise WarpError(f"{name} must be a finite 4x4 matrix")
    return a


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class View:
    """The camera: ``camera_to_world`` (Blender's ``matrix_world``; it looks down
    local -Z, +Y up) and ``projection`` (camera -> OpenGL clip, with sensor fit and lens shift)."""

    camera_to_world: np.ndarray
    projection: np.ndarray
    near: float
    far: float
    resolution: tuple[int, int] = (1920, 1080)
    orthographic: bool = False

    def __post_init__(self):
        # Own read-only copies: what is derived from them below is computed once.
        object.__setattr__(self, "camera_to_world", _frozen(_mat4(self.camera_to_world, "camera matrix_world").copy()))
        object.__setattr__(self, "projection", _frozen(_mat4(self.projection, "camera projection").copy()))
        if not (0 < self.near < self.far and math.isfinite(self.far)):
            raise WarpError(f"camera clip range must satisfy 0 < near < far (got near={self.near}, far={self.far})")
        w, h = (int(v) for v in self.resolution)
        if w < 1 or h < 1:
            raise WarpError(f"camera resolution must be positive (got {self.resolution})")
        object.__setattr__(self, "resolution", (w, h))

    @classmethod
    def perspective(cls, camera_to_world, fov_y, aspect, near, far, resolution=(1920, 1080)) -> "View":
        """A symmetric perspective camera with vertical field of view ``fov_y`` (radians)."""
        if not (0 < fov_y < math.pi):
            raise WarpError(f"fov_y must be in (0, 180) degrees (got {math.degrees(fov_y)})")
        return cls(camera_to_world, perspective_matrix(fov_y, aspect, near, far), near, far, resolution)

    def sees_depths(self, near: float, far: float) -> bool:
        """Whether eye depths from ``near`` to ``far`` overlap the clip range (a part of them can be seen)."""
        return far > self.near and near < self.far

    # A View is immutable, so what is derived from it is computed once (read-only arrays).
    @cached_property
    def world_to_camera(self) -> np.ndarray:
        return _frozen(np.linalg.inv(self.camera_to_world))

    @cached_property
    def world_to_clip(self) -> np.ndarray:
        return _frozen(self.projection @ self.world_to_camera)

    @property
    def position(self) -> np.ndarray:
        return self.camera_to_world[:3, 3].copy()

    @cached_property
    def direction(self) -> np.ndarray:
        """Unit view direction in world space (the camera's local -Z)."""
        return _frozen(normalize(-self.camera_to_world[:3, 2]))

    @cached_property
    def up(self) -> np.ndarray:
        return _frozen(normalize(self.camera_to_world[:3, 1]))

    @property
    def fov_y(self) -> float:
        """Vertical field of view (radians) of a symmetric perspective projection."""
        return 2.0 * math.atan(1.0 / self.projection[1, 1])

    @property
    def fov_x(self) -> float:
        return 2.0 * math.atan(1.0 / self.projection[0, 0])

    def corners(self) -> np.ndarray:
        """(8, 3) world-space corners of the view frustum V in ``geometry.UNIT_CUBE_CORNERS`` order."""
        return self._corners

    @cached_property
    def _corners(self) -> np.ndarray:
        # camera_to_world @ projection⁻¹: one inverse instead of inverting world_to_clip.
        inv = self.camera_to_world @ np.linalg.inv(self.projection)
        return _frozen(transform_points(inv, UNIT_CUBE_CORNERS))

    def eye_depth(self, points) -> np.ndarray:
        """Distance along the view direction (positive in front) of (N, 3) points."""
        row = self.world_to_camera[2]
        return -(np.asarray(points, dtype=np.float64).reshape(-1, 3) @ row[:3] + row[3])


LIGHT_TYPES = ("SUN", "POINT", "SPOT")


@dataclass(frozen=True)
class Light:
    """A light: ``direction`` the light travels (SUN, SPOT), ``position`` (POINT, SPOT), ``spot_angle`` the full
    cone angle in radians (an AREA light arrives as a SPOT)."""

    type: str
    direction: Optional[np.ndarray] = None
    position: Optional[np.ndarray] = None
    spot_angle: float = math.radians(45.0)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    energy: float = 1.0
    name: str = "Light"

    def __post_init__(self):
        if self.type not in LIGHT_TYPES:
            raise WarpError(f"light '{self.name}': unsupported type {self.type!r}; use one of {', '.join(LIGHT_TYPES)}")
        if self.type in ("SUN", "SPOT"):
            if self.direction is None:
                raise WarpError(f"light '{self.name}' ({self.type}) needs a direction")
            try:
                object.__setattr__(self, "direction", normalize(self.direction))
            except ValueError:
                raise WarpError(f"light '{self.name}': direction must be a non-zero finite vector") from None
        if self.type in ("POINT", "SPOT"):
            if self.position is None:
                raise WarpError(f"light '{self.name}' ({self.type}) needs a position")
            p = np.asarray(self.position, dtype=np.float64)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise WarpError(f"light '{self.name}': position must be 3 finite numbers")
            object.__setattr__(self, "position", p)
        if self.type == "SPOT" and not (0 < self.spot_angle < math.pi):
            raise WarpError(f"light '{self.name}': spot angle must be in (0, 180) degrees")

    @property
    def is_directional(self) -> bool:
        return self.type == "SUN"

    def homogeneous_from(self, origin) -> list:
        """The light relative to ``origin``, homogeneous, as 4 floats: (x, y, z, 1), or (-direction, 0) for a sun."""
        if self.is_directional:
            return [*(-self.direction).tolist(), 0.0]
        return [*(self.position - np.asarray(origin, dtype=np.float64)).tolist(), 1.0]

    def rays_to(self, points) -> np.ndarray:
        """Unit light-travel directions arriving at (N, 3) points."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if self.is_directional:
            return np.broadcast_to(self.direction, pts.shape).copy()
        d = pts - self.position
        return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass(frozen=True)
class SceneBounds:
    """World boxes ``[[min x, y, z], [max x, y, z]]``: ``casters`` and ``receivers``. ``solid``: each box is its
    object (box scenes: a ray meeting it sees its face there); False: each bounds an object that need not fill it (a
    Blender object's bounds), and a ray meeting it may see through it."""

    casters: np.ndarray
    receivers: np.ndarray
    solid: bool = True

    def __post_init__(self):
        for name in ("casters", "receivers"):
            b = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1, 2, 3)
            if not np.all(np.isfinite(b)):
                raise WarpError(f"scene {name}: box coordinates must be finite")
            if np.any(b[:, 0] > b[:, 1]):
                raise WarpError(f"scene {name}: every box needs min <= max")
            object.__setattr__(self, name, b)
        # Derived data computed once per scene on first use (e.g. body.BoxIndex for culling).
        object.__setattr__(self, "_cache", {})

    @classmethod
    def from_boxes(cls, boxes) -> "SceneBounds":
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
        return cls(b, b)

    def cached(self, key, build):
        """``build()`` once per scene under ``key`` (derived data such as culling indices)."""
        c = self._cache
        if key not in c:
            c[key] = build()
        return c[key]

    @property
    def is_empty(self) -> bool:
        return len(self.casters) == 0 and len(self.receivers) == 0

    def aabb(self) -> Optional[np.ndarray]:
        """(2, 3) box around every caster and receiver, or None for an empty scene."""
        b = np.concatenate([self.casters, self.receivers])
        return np.array([b[:, 0].min(axis=0), b[:, 1].max(axis=0)]) if len(b) else None

    def scale(self, within=None) -> float:
        """A length typical of the scene for relative tolerances: its AABB's diagonal (of its part in ``within``)."""
        box = self.aabb() if within is None or self.is_empty else np.clip(self.aabb(), *within)
        return 1.0 if box is None else max(float(np.linalg.norm(box[1] - box[0])), 1e-12)


@dataclass
class Region:
    """The part of the world a plane map serves (Chong-Gortler §3): points within ``tolerance`` of the plane
    ``dot(normal, x) = offset`` whose projection lies in the convex world-space ``polygon`` (K, 3)."""

    normal: np.ndarray
    offset: float
    polygon: np.ndarray
    tolerance: float

    def contains(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = np.asarray(self.normal, dtype=np.float64)
        poly = np.asarray(self.polygon, dtype=np.float64)
        edges = np.roll(poly, -1, axis=0) - poly
        inward = np.cross(n, edges)          # (q - a)·(n × e) = (e × (q - a))·n: p gives what its projection q does
        left = p @ inward.T - np.einsum("ij,ij->i", poly, inward) >= -self.tolerance * np.linalg.norm(edges, axis=1)
        return (np.abs(p @ n - self.offset) <= self.tolerance) & left.all(axis=1)


@dataclass
class ShadowMap:
    """One shadow map: world -> light clip ``matrix``, texel ``size``, ``depth_test``, ``role`` ("main", "cube+X",
    "plane:0", "fallback", ...); optionally the ``view_depth_range`` and ``region`` it serves, its linear
    ``depth_row`` r (z_ndc = r · [x, y, z, 1], Scherzer §4.2) and a cascade's ``blend_band``."""

    matrix: np.ndarray
    size: tuple[int, int]
    depth_test: str = "LESS"
    role: str = "main"
    view_depth_range: Optional[tuple[float, float]] = None
    region: Optional[Region] = None
    depth_row: Optional[np.ndarray] = None
    blend_band: float = 0.0

    def clip(self, points) -> np.ndarray:
        return transform_h(self.matrix, points)

    def stored_depth(self, points) -> tuple[np.ndarray, np.ndarray]:
        """The NDC depth this map stores for (N, 3) world ``points`` (its ``depth_row``, else z / w) and its gradient
        per metre, (N,) and (N, 3); not finite where w = 0."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if self.depth_row is not None:
            row = np.asarray(self.depth_row, dtype=np.float64)
            return p @ row[:3] + row[3], np.broadcast_to(row[:3], p.shape)
        h = self.clip(p)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = h[:, 2] / h[:, 3]
            return z, (self.matrix[2, :3] - z[:, None] * self.matrix[3, :3]) / h[:, 3:]

    def contains(self, points, tol: float = 0.0) -> np.ndarray:
        """Which (N, 3) points are inside the clip volume (w > 0, |ndc| <= 1 + tol)."""
        h = self.clip(points)
        ok = h[:, 3] > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ndc = h[:, :3] / np.where(ok, h[:, 3], 1.0)[:, None]
        return ok & np.all(np.abs(ndc) <= 1.0 + tol, axis=1)

    def serves(self, points, view: Optional[View] = None, tol: float = 0.0) -> np.ndarray:
        """Which points this map is responsible for: its clip volume, region (plane maps) and view depth range."""
        ok = self.contains(points, tol)
        if self.region is not None:
            ok &= self.region.contains(points)
        if self.view_depth_range is not None and view is not None:
            d = view.eye_depth(points)
            ok &= (d >= self.view_depth_range[0]) & (d <= self.view_depth_range[1])
        return ok


@dataclass
class ShadowSetup:
    """The result of every method: maps in selection order plus diagnostics."""

    maps: list[ShadowMap]
    diagnostics: Diagnostics

    def map_index(self, points, view: Optional[View] = None, tol: float = 0.0) -> np.ndarray:
        """For (N, 3) points, the index of the first map that serves each, or -1."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        idx = np.full(len(p), -1, dtype=np.int64)
        for i, m in enumerate(self.maps):
            free = idx < 0
            if not free.any():
                break
            hit = np.zeros(len(p), dtype=bool)
            hit[free] = m.serves(p[free], view, tol)
            idx[hit] = i
        return idx


MAX_MAP_SIDE = 16384
"""The longest side of any shadow map, in texels: the GPU's largest texture (shared notes §8.8)."""
CHOICES = {"focus": ("visible", "view"), "delta_z": ("body", "visible"), "lambda_guard": ("all", "glpr", "off"),
           "plane_twist": ("auto", "on", "off"), "cascade_warp": ("uniform", "psm", "lispsm", "gmnpr", "auto"),
           "cascade_budget": ("per_map", "shared")}
"""The ``WarpOptions`` fields that name one of a few choices, and those choices (their meanings: ``WarpOptions``)."""


@dataclass(frozen=True)
class WarpOptions:
    """Every method's knobs, with the defaults a fresh scene gets.

    shadow_map_size: texels (w, h) of each map.
    focus: B fitted to what the camera sees ("visible": ``visibility``) or to the whole view frustum ("view",
        Scherzer §4.1 as printed).
    texel_snapping: snap the uniform map's window to whole texels.
    delta_z: Scherzer Eq. 1's Δz, "body" (B's extent) or "visible" (``visible_depth_range``); n_opt only, never B.
    middle_vector: B's middle vector as V_P (Scherzer §4.4) instead of Eq. 3.
    linear_z: every map gets a linear ``depth_row`` (Scherzer §4.2).
    lam: a forced λ for GMNPR and GLPR (None: their rules).
    lambda_guard: whose λ is kept no worse than the uniform map: "all", "glpr", "off" (docs/papers.md, "The λ
        guard"); a forced ``lam`` never is.
    max_frustum_angle: a point light's widest single perspective map (radians).
    planes, plane_budget, plane_twist: plane_optimal's planes of interest, its largest share of the texel budget,
        its twist ("auto", "on", "off").
    cascade_splits, cascade_warp, cascade_lambda, cascade_adaptive, cascade_stable,
    cascade_budget, cascade_blend: the cascade's split count (1-8), each split's warp (or "auto"), PSSM's λ,
        Lloyd-model splits, stable splits and sun maps, "per_map" or "shared" texels, the blend band (``cascade``)."""

    shadow_map_size: tuple[int, int] = (2048, 2048)
    focus: str = "visible"
    texel_snapping: bool = False
    delta_z: str = "body"
    visible_depth_range: Optional[tuple[float, float]] = None
    middle_vector: bool = False
    linear_z: bool = True
    lam: Optional[float] = None
    lambda_guard: str = "all"
    max_frustum_angle: float = math.radians(120.0)
    planes: tuple = ()
    plane_budget: float = 0.75
    plane_twist: str = "auto"
    cascade_splits: int = 4
    cascade_warp: str = "auto"
    cascade_lambda: float = 0.5
    cascade_adaptive: bool = True
    cascade_stable: bool = False
    cascade_budget: str = "per_map"
    cascade_blend: float = 0.1

    def __post_init__(self):
        size = self.shadow_map_size
        if isinstance(size, (int, np.integer)):
            size = (int(size), int(size))
        w, h = (int(v) for v in size)
        if not (1 <= w <= MAX_MAP_SIDE and 1 <= h <= MAX_MAP_SIDE):
            raise WarpError(f"shadow map size must be between 1 and {MAX_MAP_SIDE} texels per side (got {w}x{h})")
        object.__setattr__(self, "shadow_map_size", (w, h))
        for name, choices in CHOICES.items():
            if getattr(self, name) not in choices:
                raise WarpError(f"{name} must be one of {', '.join(map(repr, choices))} (got {getattr(self, name)!r})")
        if not (0.0 < self.plane_budget <= 1.0):
            raise WarpError(f"plane_budget must be in (0, 1] (got {self.plane_budget!r})")
        splits = self.cascade_splits
        if isinstance(splits, bool) or not isinstance(splits, (int, np.integer)) or not 1 <= splits <= 8:
            raise WarpError(f"cascade_splits must be a whole number from 1 to 8 (got {splits!r})")
        object.__setattr__(self, "cascade_splits", int(splits))
        if not 0.0 <= self.cascade_lambda <= 1.0:
            raise WarpError(f"cascade_lambda must be in [0, 1] (got {self.cascade_lambda!r})")
        if not 0.0 <= self.cascade_blend <= 0.5:
            raise WarpError(f"cascade_blend must be in [0, 0.5] (got {self.cascade_blend!r})")
