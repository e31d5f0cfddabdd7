"""Lixel's shaders, built from ``gpu_shaders/*.glsl`` with ``GPUShaderCreateInfo``
(the one way Blender 4.2 through 5.0 all accept; shared notes §2).

Variants are selected with ``#define`` and cached per process. The linear-z
depth pass writes ``gl_FragDepth``; it is declared with ``depth_write("ANY")``
where that exists (Blender 4.2 lacks it and compiles ``gl_FragDepth`` without).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..warp.types import WarpError
from .layout import LIXEL_SHADE, MAX_MAPS, MAX_POLYGON  # noqa: F401 (MAX_* re-exported)

SHADER_DIR = Path(__file__).resolve().parents[2] / "gpu_shaders"

INSTANCES_PER_ROW = 4096
"""Instances per row of the instance textures (matrices: 4 texels each, 16384 wide; ids: 1 texel each)."""
INSTANCE_SLOT = MAX_MAPS
"""Sampler slot of the instance matrices (after the shading pass's maps)."""
IDS_SLOT = MAX_MAPS + 1
"""Sampler slot of a pass's draw list (instance ids)."""


class ShaderBuildError(WarpError):
    pass


@functools.lru_cache(maxsize=None)
def source(name: str) -> str:
    path = SHADER_DIR / name
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ShaderBuildError(f"Lixel's shader file {path} is missing ({exc}): reinstall the extension") from None


def _create(info, what: str):
    import gpu
    try:
        return gpu.shader.create_from_info(info)
    except Exception as exc:  # Blender raises a bare Exception; the GLSL log is on stderr
        raise ShaderBuildError(f"Lixel's {what} shader failed to compile ({exc}); see the console") from None


def _common_defines(info) -> None:
    info.define("LIXEL_INSTANCES_PER_ROW", str(INSTANCES_PER_ROW))
    info.define("LIXEL_MAX_MAPS", str(MAX_MAPS))
    info.define("LIXEL_MAX_POLYGON", str(MAX_POLYGON))


def _instanced_vertex_input(info) -> None:
    """The vertex inputs of an instanced draw (``instance_lib.glsl``)."""
    info.vertex_in(0, "VEC3", "pos")
    info.push_constant("INT", "u_instance_offset")
    info.sampler(INSTANCE_SLOT, "FLOAT_2D", "u_instances")
    info.sampler(IDS_SLOT, "FLOAT_2D", "u_ids")


@functools.lru_cache(maxsize=None)
def depth_shader(linear_z: bool):
    """Depth pass. ``linear_z`` writes ``gl_FragDepth`` from the map's window
    depth row (Scherzer §4.2), carried in one perspective-correct varying;
    otherwise the fragment stage is empty (a bare draw)."""
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    _common_defines(info)
    if linear_z:
        info.define("LIXEL_LINEAR_Z")
        iface = gpu.types.GPUStageInterfaceInfo("lixel_depth_iface")
        iface.smooth("FLOAT", "v_depth")
        info.vertex_out(iface)
        info.push_constant("VEC4", "u_depth_row")
        if hasattr(info, "depth_write"):
            info.depth_write("ANY")
    _instanced_vertex_input(info)
    info.push_constant("MAT4", "u_light")
    info.vertex_source(source("instance_lib.glsl") + source("depth_vert.glsl"))
    info.fragment_source(source("depth_frag.glsl") if linear_z else source("bare_frag.glsl"))
    return _create(info, "depth pass")


@dataclass(frozen=True)
class ShadeVariant:
    """What a shading-pass variant compiles in (``gpu_shaders/shade_frag.glsl``
    explains why each is a define and not a branch)."""

    map_count: int = 1
    light: str = "SUN"
    """SUN, POINT or SPOT."""
    pcf: int = 3
    mdsm: int = 1
    """Depths per texel (n); > 1 samples RGBA32F key maps."""
    revectorize: bool = False
    """``ShadowSettings.revectorize``: PCF 2 follows straight shadow edges past the texel staircase."""
    bias: str = "RECEIVER_PLANE"
    """``ShadowSettings.bias_mode`` (LIXEL_BIAS)."""
    regions: bool = False
    ranges: bool = False
    blends: bool = False
    """Some map has a blend band (a cascade's seams)."""
    blurred: bool = False
    """The eye-space blur follows: the colour target gets the unshadowed light."""
    shadow_alpha: bool = True
    """Write the shadow (the Shadow pass) into the colour target's alpha; the
    combined image's alpha, always 1, is set when it is read back
    (``ShadowFrame.finish``). A second target costs the shading pass more than
    the split costs the read-back (docs/performance.md)."""
    footprint: bool = True
    """Write the footprint heatmap (the Footprint pass)."""
    data: bool = False
    """Also write (shadow, map index, texels per pixel, eye depth)."""

    world: bool = False
    """Also write the world position."""
    holdout: bool = False
    """Some receiver drawn is held out: its pixels get the (0, 0, 0, 0) of a transparent hole (LIXEL_HOLDOUT)."""
    unlit: bool = False
    """Some receiver drawn is not lit by the light (Light Linking): its pixels get no light and no shadow of it
    (LIXEL_UNLIT)."""
    linear_z: Optional[bool] = None
    """Every map stores its linear depth row (True), none does (False), or they
    differ (None: read per map, both sides evaluated); see :func:`agreed`."""
    greater: Optional[bool] = None
    """Every map's depth test is GREATER (True), none's is (False), or they differ (None)."""

    def __post_init__(self):
        if not 1 <= self.map_count <= MAX_MAPS:
            raise ShaderBuildError(f"the shading pass takes 1 to {MAX_MAPS} maps (got {self.map_count})")

    @property
    def outputs(self) -> tuple[str, ...]:
        """The fragment outputs, in target order."""
        return ("out_color",) + \
            (("out_footprint",) if self.footprint else ()) + (("out_data",) if self.data else ()) + \
            (("out_world",) if self.world else ())

    @property
    def flags(self) -> dict:
        """The GLSL defines of the optional targets."""
        return {"LIXEL_SHADOW_ALPHA": self.shadow_alpha, "LIXEL_FOOTPRINT": self.footprint,
                "LIXEL_DATA": self.data, "LIXEL_WORLD": self.world}


def agreed(flags) -> Optional[bool]:
    """The one value all ``flags`` share, or None where they differ (a
    :class:`ShadeVariant` field that is compiled in only when every map agrees)."""
    values = set(bool(f) for f in flags)
    return values.pop() if len(values) == 1 else None


LIGHT_CODES = {"SUN": 0, "POINT": 1, "SPOT": 2}
BIAS_CODES = {"NONE": 0, "CONSTANT": 1, "SLOPE": 2, "CONSTANT_SLOPE": 3, "RECEIVER_PLANE": 4, "NORMAL_OFFSET": 5}
"""``ShadowSettings.bias_mode`` as the shading pass's LIXEL_BIAS_* codes."""


def _camera_info(name: str, fragment: str):
    """A draw of the receivers from the camera (``shade_vert.glsl``) with ``fragment``."""
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    _common_defines(info)
    iface = gpu.types.GPUStageInterfaceInfo(f"lixel_{name}_iface")
    iface.smooth("VEC3", "v_world")
    iface.smooth("VEC3", "v_camera")
    iface.smooth("VEC3", "v_from_camera")
    for flat in ("v_camera_offsets", "v_camera_to_world_x", "v_camera_to_world_y", "v_camera_to_world_z"):
        iface.flat("VEC3", flat)                                 # (camera_lib.glsl: solved once per vertex)
    info.vertex_out(iface)
    _instanced_vertex_input(info)
    info.push_constant("MAT4", "u_view_proj")
    info.vertex_source("#define LIXEL_VERTEX_STAGE\n" + source("instance_lib.glsl") + source("camera_lib.glsl")
                       + source("shade_vert.glsl"))
    info.fragment_source(source("camera_lib.glsl") + source(fragment))
    return info


@functools.lru_cache(maxsize=None)
def prepass_shader(holdout: bool = False, unlit: bool = False):
    """The camera's pre-pass: depth, and the surface seen (position, and the
    normal packed beside it in one target) for the shading pass
    (``prepass_frag.glsl``); ``holdout``: for held-out receivers, whose packed
    normal gets its sign bit set (LIXEL_HOLDOUT); ``unlit``: for receivers the
    light does not light (Light Linking), bit 29 instead of 30 (LIXEL_UNLIT)."""
    info = _camera_info("prepass" + "_holdout" * holdout + "_unlit" * unlit, "prepass_frag.glsl")
    if holdout:
        info.define("LIXEL_HOLDOUT")
    if unlit:
        info.define("LIXEL_UNLIT")
    info.fragment_out(0, "VEC4", "out_surface")
    return _create(info, "camera pre-pass")


@functools.lru_cache(maxsize=None)
def camera_depth_shader():
    """A bare depth draw from the camera (empty fragment stage): the floor the
    benchmark measures the pre-pass against."""
    return _create(_camera_info("camera_depth", "bare_frag.glsl"), "camera depth")


SURFACE_SLOT = MAX_MAPS
"""Sampler slot of the pre-pass surface (position and packed normal) in the shading pass."""


def _shade_info(variant: ShadeVariant):
    v = variant
    info = _fullscreen_info("shade_frag.glsl", at_far=True)
    info.define("LIXEL_MAP_COUNT", str(v.map_count))
    info.define("LIXEL_LIGHT", str(LIGHT_CODES[v.light]))
    info.define("LIXEL_PCF", str(int(v.pcf)))
    if v.mdsm > 1:
        info.define("LIXEL_MDSM", str(int(v.mdsm)))
    info.define("LIXEL_BIAS", str(BIAS_CODES[v.bias]))
    flags = {"LIXEL_REGIONS": v.regions, "LIXEL_RANGES": v.ranges, "LIXEL_BLENDS": v.blends,
             "LIXEL_BLURRED": v.blurred, "LIXEL_HOLDOUT": v.holdout, "LIXEL_UNLIT": v.unlit,
             "LIXEL_REVECTORIZE": v.revectorize and v.pcf == 2 and v.mdsm == 1, **v.flags}
    for name, on in flags.items():
        if on:
            info.define(name, "1")
    for name, value in (("LIXEL_MAPS_LINEAR", v.linear_z), ("LIXEL_MAPS_GREATER", v.greater)):
        if value is not None:
            info.define(name, "1" if value else "0")
    info.typedef_source(LIXEL_SHADE.glsl())
    info.uniform_buf(0, LIXEL_SHADE.name, "lixel")
    for i in range(MAX_MAPS):
        info.sampler(i, "FLOAT_2D" if v.mdsm > 1 else "DEPTH_2D", f"u_map{i}")
    info.sampler(SURFACE_SLOT, "FLOAT_2D", "u_surface")

    for slot, name in enumerate(v.outputs):
        info.fragment_out(slot, "VEC4", name)
    return info


@functools.lru_cache(maxsize=None)
def shade_shader(variant: ShadeVariant):
    """The shading pass, compiled for ``variant`` (once per process): one
    full-screen pass over the pre-pass surface (``shade_frag.glsl``)."""
    return _create(_shade_info(variant), "shading pass")


def _fullscreen_info(name: str, at_far: bool = False):
    """A full-screen pass (``fullscreen_vert.glsl``) with ``gpu_shaders/<name>``;
    ``at_far``: on the far plane (depth tested against what was drawn)."""
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    if at_far:
        info.define("LIXEL_AT_FAR")
    info.vertex_in(0, "VEC3", "pos")
    info.vertex_source(source("fullscreen_vert.glsl"))
    info.fragment_source(source(name))
    return info


def background_shader(variant: ShadeVariant):
    """Every target of a shading pass of ``variant`` where no receiver is seen
    (``background_frag.glsl``)."""
    return _background_shader(variant.outputs, tuple(sorted(n for n, on in variant.flags.items() if on)))


@functools.lru_cache(maxsize=None)
def _background_shader(outputs: tuple, defines: tuple):
    info = _fullscreen_info("background_frag.glsl", at_far=True)
    info.push_constant("VEC4", "u_background")
    for name in defines:
        info.define(name, "1")
    for slot, name in enumerate(outputs):
        info.fragment_out(slot, "VEC4", name)
    return _create(info, "shading background")


@functools.lru_cache(maxsize=None)
def compose_shader():
    """The combined image and shadow mask after the eye-space blur (``compose_frag.glsl``)."""
    info = _fullscreen_info("compose_frag.glsl")
    info.sampler(0, "FLOAT_2D", "u_direct")
    info.sampler(1, "FLOAT_2D", "u_mask")
    info.push_constant("VEC4", "u_ambient")
    info.push_constant("VEC4", "u_background")
    info.fragment_out(0, "VEC4", "out_combined")
    return _create(info, "compose")


@functools.lru_cache(maxsize=None)
def eye_blur_shader():
    """The depth-dependent eye-space blur of the shadow (Scherzer §4.3, ``eye_blur_frag.glsl``)."""
    info = _fullscreen_info("eye_blur_frag.glsl")
    info.sampler(0, "FLOAT_2D", "u_data")
    info.push_constant("VEC4", "u_blur")
    info.fragment_out(0, "VEC4", "out_mask")
    return _create(info, "eye-space blur")


@functools.lru_cache(maxsize=None)
def map_preview_shader(stretch: bool):
    """A shadow map resampled to a picture (``map_preview_frag.glsl``): its
    window depth, or (``stretch``) a grey picture stretched over the depths written."""
    info = _fullscreen_info("map_preview_frag.glsl")
    if stretch:
        info.define("LIXEL_STRETCH")
    info.sampler(0, "DEPTH_2D", "u_map")
    info.push_constant("VEC4", "u_range")
    info.push_constant("FLOAT", "u_step")
    info.fragment_out(0, "VEC4", "out_preview")
    return _create(info, "shadow-map preview")


@functools.lru_cache(maxsize=None)
def reduce_shader(depth_source: bool):
    """One step of a min/max reduction (``reduce_frag.glsl``): each output
    texel holds the (least, greatest) value below a cut-off over a block of the
    source; ``depth_source`` reads a depth texture."""
    info = _fullscreen_info("reduce_frag.glsl")
    info.sampler(0, "DEPTH_2D" if depth_source else "FLOAT_2D", "u_source")
    info.push_constant("VEC4", "u_reduce")
    info.fragment_out(0, "VEC4", "out_range")
    return _create(info, "reduction")


@functools.lru_cache(maxsize=None)
def mdsm_shader():
    """Builds an n-depth key map from a depth map (Pagot et al. §4.3)."""
    info = _fullscreen_info("mdsm_frag.glsl")
    info.push_constant("VEC4", "u_params")
    info.sampler(0, "DEPTH_2D", "u_depth")
    info.fragment_out(0, "VEC4", "out_keys")
    return _create(info, "multiple-depth map")
