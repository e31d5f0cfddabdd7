"""Lixel's render settings as plain data (no bpy): what the scene's Lixel panel
edits and what the gpu pipeline, render engine, scripts and report consume.

``addon.ui.properties`` mirrors these fields as a PropertyGroup on the Scene and
converts with ``to_settings()``; defaults here give a good result on a fresh
scene with a camera and a sun.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from .warp.types import MAX_MAP_SIDE, WarpOptions, WarpError

MIN_MAP_SIZE = 16
MAX_MAP_SIZE = MAX_MAP_SIDE
"""A scene's shadow map side in texels: at most the GPU's largest texture (shared
notes §8.8); below 16 texels a map cannot resolve a shadow, so a smaller value is
a typing slip that Lixel refuses rather than renders."""

MAX_EYE_BLUR = 32.0
"""The widest eye-space blur in pixels: each seen pixel reads its (2r + 1)² neighbours (eye_blur_frag.glsl), 4,225 at
32 and 4 million at 1,000, where one 1080p frame takes hours and the viewport's shadowed overlay freezes Blender."""

BIAS_MODES = ("NONE", "CONSTANT", "SLOPE", "CONSTANT_SLOPE", "RECEIVER_PLANE", "NORMAL_OFFSET")
MDSM_SELECTIONS = ("MINMAX", "SORT")


@dataclass(frozen=True)
class ShadowSettings:
    """Filtering and biasing (Scherzer §4.2-4.3, Pagot et al. §4).

    Biases are in texels of the receiver itself: one unit is the world width,
    across the light ray, of the map texel that holds the receiving point, so
    the same numbers fit every method, light, map size and scene scale (see
    gpu_shaders/shade_frag.glsl). ``bias_mode``: RECEIVER_PLANE compares every
    PCF tap with the receiver's own plane there, or its own depth where that
    plane recedes from the light (no acne on any plane, no shadow moved), less
    ``constant_bias``; NORMAL_OFFSET looks up the point moved ``normal_offset``
    texels along its normal, less ``constant_bias``; CONSTANT / SLOPE /
    CONSTANT_SLOPE are the classic offsets (``slope_bias`` multiplies the
    receiver's depth change over the PCF reach). ``revectorize``: PCF 2 (one
    depth per texel) puts a straight shadow edge on the line through the ends
    of its texel staircase's runs, not on the stairs (shade_frag.glsl,
    lixel_run; off by default: docs/papers.md, "Revectorized edges"). The
    defaults were chosen on the rendered-error scenes (bench/rendered_error.py;
    docs/papers.md)."""

    bias_mode: str = "RECEIVER_PLANE"
    constant_bias: float = 1.0         # texels of the receiver, along the light ray
    slope_bias: float = 1.0            # SLOPE modes: multiples of the depth change over the PCF reach
    normal_offset: float = 1.0         # NORMAL_OFFSET: texels of the receiver, along its normal
    back_faces: bool = False           # render back faces into the map (Scherzer §4.2)
    pcf_kernel: int = 2                # k in k x k PCF, 1..5 (odd k: a box; even k: bilinear taps, 2 = hardware PCF)
    revectorize: bool = False          # PCF 2: straight shadow edges followed past the texel staircase (shade_frag.glsl)
    mdsm_depths: int = 1               # n of n-SM, 1..4 (MDSM §4.2)
    mdsm_selection: str = "MINMAX"     # MDSM §4.3
    mdsm_neighbourhood: int = 3        # q of the q x q neighbourhood
    eye_blur: float = 0.0              # depth-dependent eye-space blur radius in pixels (Scherzer §4.3), 0 = off

    def __post_init__(self):
        if self.bias_mode not in BIAS_MODES:
            raise WarpError(f"bias mode must be one of {', '.join(BIAS_MODES)}")
        if not 1 <= self.pcf_kernel <= 5:
            raise WarpError(f"PCF kernel must be 1..5 (got {self.pcf_kernel})")
        if not 1 <= self.mdsm_depths <= 4:
            raise WarpError(f"MDSM depth count must be 1..4 (got {self.mdsm_depths})")
        if self.mdsm_selection not in MDSM_SELECTIONS:
            raise WarpError(f"MDSM selection must be one of {', '.join(MDSM_SELECTIONS)}")
        if not all(b >= 0 for b in (self.constant_bias, self.slope_bias, self.normal_offset)):   # NaN too
            raise WarpError("biases must be >= 0")
        if not 0 <= self.eye_blur <= MAX_EYE_BLUR:
            raise WarpError(f"eye-space blur must be 0..{MAX_EYE_BLUR:g} pixels (got {self.eye_blur:g})")


@dataclass(frozen=True)
class LixelSettings:
    method: str = "lispsm"
    warp: WarpOptions = field(default_factory=WarpOptions)
    shadow: ShadowSettings = field(default_factory=ShadowSettings)

    def with_method(self, method: str) -> "LixelSettings":
        return replace(self, method=method)
