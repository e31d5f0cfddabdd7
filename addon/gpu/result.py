"""What a Lixel frame returns: :class:`RenderResult`.

The frame stays on the GPU; only the images a caller names are read back
(``render_shadows(..., read=...)``), each once, as float32 (the map index as
int32, coverage as bool). Images have row 0 at the bottom (Blender's
render-result order); an image not asked for is None.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Optional

import numpy as np

ANALYSIS = frozenset({"combined", "shadow_mask", "shadow_raw", "covered", "eye_depth", "map_index",
                      "texels_per_pixel", "footprint_heatmap"})
"""The per-pixel images of the shading pass (the default read)."""
EVERYTHING = ANALYSIS | {"world_position", "world_normal", "shadow_map_preview", "shadow_maps", "mdsm_keys"}
SURFACE = frozenset({"world_position", "world_normal"})
"""The surface the pre-pass saw (one target, read together)."""


@dataclass
class RenderCounts:
    """What a frame drew and uploaded."""

    maps: int = 0
    instances: int = 0
    casters_drawn: int = 0
    casters_culled: int = 0
    """Instances that cast shadows but cannot shadow what the camera sees."""
    non_casters: int = 0
    caster_triangles_drawn: int = 0
    caster_triangles_culled: int = 0
    receivers_drawn: int = 0
    receiver_triangles_drawn: int = 0
    uploads: int = 0
    """Mesh batches uploaded (new or changed meshes)."""
    uploaded_triangles: int = 0
    matrix_uploads: int = 0
    """Uploads of the instance matrices (the scene's instances changed)."""
    list_uploads: int = 0
    """Draw lists uploaded (the culling chose other instances than last frame)."""
    target_allocations: int = 0
    """Render targets allocated (a new size, or the first frame)."""


@dataclass
class RenderMemory:
    """GPU memory of a frame, bytes."""

    per_map_bytes: list = field(default_factory=list)
    mdsm_bytes_per_layer: list = field(default_factory=list)
    mdsm_texture_bytes: list = field(default_factory=list)
    render_target_bytes: int = 0


@dataclass
class RenderResult:
    """One Lixel frame. Per-pixel images are (H, W[, C]) with row 0 at the bottom."""

    combined: Optional[np.ndarray] = None
    """(H, W, 4) ambient * albedo + direct * (1 - shadow), the world colour behind."""
    shadow_mask: Optional[np.ndarray] = None
    """(H, W) 0 lit .. 1 fully shadowed (after the eye-space blur)."""
    shadow_raw: Optional[np.ndarray] = None
    """(H, W) the same before the eye-space blur."""
    covered: Optional[np.ndarray] = None
    """(H, W) bool: a surface is seen."""
    world_position: Optional[np.ndarray] = None
    """(H, W, 3) float64 (computed in float32 relative to the frame's origin), NaN where nothing is seen."""
    world_normal: Optional[np.ndarray] = None
    """(H, W, 3) the unit geometric normal of the triangle seen (its side as the pre-pass's screen derivatives
    give it; within about 5e-4 rad), NaN where nothing is seen: which surface the pixel shows."""
    eye_depth: Optional[np.ndarray] = None
    """(H, W) distance along the view direction, inf where nothing is seen."""
    map_index: Optional[np.ndarray] = None
    """(H, W) int32: the map used, -1 where none serves the point or nothing is seen."""
    texels_per_pixel: Optional[np.ndarray] = None
    """(H, W) shadow-map texels per pixel (the footprint), 0 where nothing is seen."""
    footprint_heatmap: Optional[np.ndarray] = None
    """(H, W, 4) the footprint as colours (see ``gpu_shaders/compose_frag.glsl``)."""
    shadow_map_preview: Optional[np.ndarray] = None
    """(H, W) the first map's window depth resampled to the render size."""
    shadow_maps: list = field(default_factory=list)
    """Window depth per map, (h, w) each (when read)."""
    mdsm_keys: list = field(default_factory=list)
    """n-depth keys per map, (h, w, 4) each, when n > 1 (when read)."""
    timings: dict = field(default_factory=dict)
    """Stage name -> seconds."""
    counts: RenderCounts = field(default_factory=RenderCounts)
    memory: RenderMemory = field(default_factory=RenderMemory)

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frame's images."""
        for name in ("combined", "shadow_mask", "covered", "shadow_raw", "eye_depth", "footprint_heatmap"):
            img = getattr(self, name)
            if img is not None:
                return img.shape[1], img.shape[0]
        raise ValueError("no image was read back")


def unpack_normals(codes) -> np.ndarray:
    """(..., 3) unit normals from the pre-pass's packed floats (``prepass_frag.glsl``: octahedral coordinates in
    14 and 15 bits of one float; ``lixel_unpack_normal`` and ``lixel_unoctahedral`` in ``shade_frag.glsl``)."""
    bits = np.ascontiguousarray(codes, dtype=np.float32).view(np.uint32)
    p = (np.stack([(bits >> 15) & 16383, bits & 32767], axis=-1) - np.array([8191.0, 16383.0])) / np.array([8191.0, 16383.0])
    n = np.concatenate([p, 1.0 - np.abs(p).sum(axis=-1, keepdims=True)], axis=-1)
    fold = np.maximum(-n[..., 2:], 0.0)
    n[..., :2] -= np.copysign(fold, n[..., :2])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def check_read(read) -> frozenset:
    """``read`` as a set of :class:`RenderResult` image names, or a clear error."""
    names = frozenset(read)
    images = {f.name for f in fields(RenderResult)} - {"timings", "counts", "memory"}
    unknown = names - images
    if unknown:
        raise ValueError(f"render_shadows cannot read {', '.join(sorted(unknown))}; "
                         f"choose from {', '.join(sorted(images))}")
    return names
