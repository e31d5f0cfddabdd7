"""What the methods share: each light frame's unwarped map fitted to its part of
B (Scherzer §4.1's focusing), the uniform method's maps, the near-plane note."""
from __future__ import annotations

import math

import numpy as np

from ..fit import divided, fit_runs, window_matrix
from ..body import IntersectionBody
from ..diagnostics import Diagnostics
from ..frame import LightFrame, body_light_angles, light_frames, world_sun_frame
from ..geometry import point_runs
from ..linear_depth import frame_depth_row
from ..types import Light, ShadowMap, ShadowSetup, View, WarpOptions

SNAP_STEPS_PER_OCTAVE = 8
"""Texel snapping: a window's extent is one of this many sizes per doubling."""

NEAR_PLANE_NOTE = ("the light is inside B and a box reaches nearer to it than the near plane "
                   "(1e-6 of B's scale); what lies nearer is not covered")
"""The "near plane" fallback's reason (``frame.LightFrame.near_clamped``)."""


def body_diagnostics(method: str, view: View, light: Light, body: IntersectionBody) -> Diagnostics:
    """``method``'s Diagnostics opened with B and its light-view angles θ, γ (``frame.body_light_angles``)."""
    return Diagnostics(method, *body_light_angles(view, light, body), body_vertices=body.vertices)


def near_plane_notes(frames: list[LightFrame], prefix: str = "") -> list[tuple[str, str]]:
    """The fallbacks to record for frames whose near plane cuts into a box (the light inside B)."""
    return [(f"{prefix}{f.role}: near plane", NEAR_PLANE_NOTE) for f in frames if f.near_clamped]


def frame_maps(frames: list[LightFrame], size: tuple[int, int], snap: bool = False,
               linear_z: bool = False) -> list[ShadowMap]:
    """The unwarped map of each light frame, fitted to its points; ``snap``: an orthographic window on whole
    texels; ``linear_z``: linear depth rows (Scherzer §4.2)."""
    if len(frames) > 1:
        fitted = fit_runs(np.array([f.to_light for f in frames]), *point_runs([f.points for f in frames]))
        maps = [ShadowMap(m, size, "LESS", f.role) for m, f in zip(fitted, frames)]
    else:
        frame = frames[0]
        ndc = divided(frame.points_h @ frame.to_light.T)
        lo, hi = ndc.min(axis=0), ndc.max(axis=0)
        if snap and frame.directional:
            lo, hi = snapped_window(lo, hi, size)
        maps = [ShadowMap(window_matrix(lo, hi) @ frame.to_light, size, "LESS", frame.role)]
    if linear_z:
        for m, f in zip(maps, frames):
            m.depth_row = frame_depth_row(f)
    return maps


def snapped_window(lo: np.ndarray, hi: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Grow the x/y window [lo, hi] to exactly ``size`` texels from a whole texel of the world-fixed lattice
    (orthographic frames only: light-space units are world units), the extent a ladder step with a texel to spare,
    so that it holds [lo, hi] wherever that lies on the lattice; a side of one texel is not snapped."""
    lo, hi = lo.copy(), hi.copy()
    for axis, texels in zip((0, 1), size):
        if texels > 1:
            spared = max(hi[axis] - lo[axis], 1e-300) * texels / (texels - 1)       # ladder - texel >= extent
            ladder = 2.0 ** (math.ceil(math.log2(spared) * SNAP_STEPS_PER_OCTAVE) / SNAP_STEPS_PER_OCTAVE)
            texel = ladder / texels
            lo[axis] = math.floor(lo[axis] / texel) * texel
            hi[axis] = lo[axis] + ladder
    return lo, hi


def uniform_setup(view: View, light: Light, body: IntersectionBody, options: WarpOptions,
                  diag: Diagnostics) -> ShadowSetup:
    """The uniform method's maps (PSM's fallback too), their near-plane notes and frames recorded in ``diag``."""
    if options.texel_snapping and light.is_directional:
        frames = [world_sun_frame(light, body)]      # a texel grid fixed in the world
    else:
        frames = light_frames(view, light, body, options)
    diag.fallbacks += near_plane_notes(frames)
    diag.extra["frames"] = [f.role for f in frames]
    return ShadowSetup(frame_maps(frames, options.shadow_map_size, options.texel_snapping, options.linear_z), diag)
