"""Lixel's shaders, built from ``gpu_shaders/*.glsl`` with ``GPUShaderCreateInfo``
(the one way Blender 4.2 through 5.0 all accept; shared notes §2).

Variants are selected with ``#define`` and cached per process. The linear-z
depth pass writes ``gl_FragDepth``; it is declared with ``depth_write("ANY")``
where that exists (Blender 4.2 lacks it and compiles ``gl_FragDepth`` without).
"""
from __future__ import annotations

import functools
from pathlib import Path

from ..warp.types import WarpError

SHADER_DIR = Path(__file__).resolve().parents[2] / "gpu_shaders"

MAX_MAPS = 8
"""Shadow maps one shading pass can select from (sampler slots 0..7)."""
MAX_POLYGON = 32
"""Vertices of a plane map's region polygon passed to the shader."""
INSTANCES_PER_ROW = 4096
"""Instance matrices per row of the instance texture (4 texels each: 16384 wide)."""
INSTANCE_SLOT = MAX_MAPS


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


@functools.lru_cache(maxsize=None)
def depth_shader(linear_z: bool):
    """Depth pass. ``linear_z`` writes ``gl_FragDepth`` from the map's depth row
    (Scherzer §4.2); otherwise the fragment stage is empty (a bare draw)."""
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    _common_defines(info)
    if linear_z:
        info.define("LIXEL_LINEAR_Z")
        iface = gpu.types.GPUStageInterfaceInfo("lixel_depth_iface")
        iface.smooth("VEC3", "v_world")
        info.vertex_out(iface)
        info.push_constant("VEC4", "u_depth_row")
        if hasattr(info, "depth_write"):
            info.depth_write("ANY")
    info.vertex_in(0, "VEC3", "pos")
    info.push_constant("MAT4", "u_light")
    info.push_constant("INT", "u_instance_offset")
    info.sampler(0, "FLOAT_2D", "u_instances")
    info.vertex_source(source("instance_lib.glsl") + source("depth_vert.glsl"))
    info.fragment_source(source("depth_frag.glsl") if linear_z else source("bare_frag.glsl"))
    return _create(info, "depth pass")


def _shade_info(prepass: bool, mdsm: bool, map_count: int = 1):
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    _common_defines(info)
    info.define("LIXEL_MAP_COUNT", str(int(map_count)))
    if mdsm:
        info.define("LIXEL_MDSM")
    iface = gpu.types.GPUStageInterfaceInfo("lixel_shade_iface")
    iface.smooth("VEC3", "v_world")
    info.vertex_out(iface)
    info.vertex_in(0, "VEC3", "pos")
    info.push_constant("MAT4", "u_view_proj")
    info.push_constant("INT", "u_instance_offset")
    info.sampler(INSTANCE_SLOT, "FLOAT_2D", "u_instances")
    info.vertex_source(source("instance_lib.glsl") + source("shade_vert.glsl"))
    if prepass:
        info.fragment_source(source("bare_frag.glsl"))
        return info
    info.typedef_source(source("lixel_types.glsl"))
    info.uniform_buf(0, "LixelShade", "lixel")
    for i in range(MAX_MAPS):
        info.sampler(i, "FLOAT_2D" if mdsm else "DEPTH_2D", f"u_map{i}")
    info.fragment_out(0, "VEC4", "out_direct")
    info.fragment_out(1, "VEC4", "out_data")
    info.fragment_out(2, "VEC4", "out_world")
    info.fragment_source(source("shade_frag.glsl"))
    return info


@functools.lru_cache(maxsize=None)
def shade_shader(mdsm: bool, map_count: int = 1):
    """Shading pass from the camera for ``map_count`` maps (1..MAX_MAPS);
    ``mdsm`` samples RGBA32F key maps."""
    if not 1 <= map_count <= MAX_MAPS:
        raise ShaderBuildError(f"the shading pass takes 1 to {MAX_MAPS} maps (got {map_count})")
    return _create(_shade_info(False, mdsm, map_count), "shading pass")


@functools.lru_cache(maxsize=None)
def prepass_shader():
    """Camera depth pre-pass (same vertex stage as the shading pass)."""
    return _create(_shade_info(True, False), "camera depth pre-pass")


@functools.lru_cache(maxsize=None)
def mdsm_shader():
    """Builds an n-depth key map from a depth map (Pagot et al. §4.3)."""
    import gpu
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC3", "pos")
    info.push_constant("VEC4", "u_params")
    info.sampler(0, "DEPTH_2D", "u_depth")
    info.fragment_out(0, "VEC4", "out_keys")
    info.vertex_source(source("fullscreen_vert.glsl"))
    info.fragment_source(source("mdsm_frag.glsl"))
    return _create(info, "multiple-depth map")
