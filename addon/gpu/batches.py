"""GPU batches (one per mesh datablock, kept across renders) and instance tables.

Every batch has a single ``pos`` attribute (local space, float32); instances
are drawn with ``GPUBatch.draw_instanced`` and fetch their object -> world
matrix from an RGBA32F texture (shared notes §3: the gpu module exposes no
per-instance vertex buffers). ``BatchCache.uploads`` counts geometry uploads
so tests can show that a second render uploads nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .shaders import INSTANCES_PER_ROW


def _vert_format():
    import gpu
    fmt = gpu.types.GPUVertFormat()
    fmt.attr_add(id="pos", comp_type="F32", len=3, fetch_mode="FLOAT")
    return fmt


def make_batch(positions: np.ndarray, triangles: np.ndarray):
    """A TRIS batch of float32 (V, 3) positions and int32 (T, 3) indices."""
    import gpu
    vbo = gpu.types.GPUVertBuf(_vert_format(), len(positions))
    vbo.attr_fill("pos", np.ascontiguousarray(positions, dtype=np.float32))
    ibo = gpu.types.GPUIndexBuf(type="TRIS", seq=np.ascontiguousarray(triangles, dtype=np.int32))
    return gpu.types.GPUBatch(type="TRIS", buf=vbo, elem=ibo)


class BatchCache:
    """GPU batches by geometry key; a batch is rebuilt only when its mesh's
    content (version and fingerprint) changed."""

    def __init__(self):
        self._entries: dict = {}
        self.uploads = 0
        self.uploaded_triangles = 0

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, mesh):
        ident = (mesh.version, mesh.fingerprint)
        entry = self._entries.get(mesh.key)
        if entry is not None and entry[0] == ident:
            return entry[1]
        batch = make_batch(mesh.positions, mesh.triangles)
        self._entries[mesh.key] = (ident, batch)
        self.uploads += 1
        self.uploaded_triangles += mesh.triangle_count
        return batch

    def prune(self, keep) -> None:
        """Drop batches whose key is not in ``keep``."""
        for k in [k for k in self._entries if k not in keep]:
            del self._entries[k]


_shared = None


def shared_batches() -> BatchCache:
    """The process-wide batch cache (lives as long as the GPU context)."""
    global _shared
    if _shared is None:
        _shared = BatchCache()
    return _shared


@dataclass
class DrawGroup:
    """Instances of one batch with the same handedness, drawn in one call."""

    key: tuple
    offset: int
    count: int
    mirrored: bool
    triangles: int


@dataclass
class InstanceTable:
    """Matrices of the instances to draw, packed into one RGBA32F texture,
    grouped by batch and handedness (a mirroring matrix flips winding, which
    matters when culling faces)."""

    texture: object
    groups: list = field(default_factory=list)
    instance_count: int = 0

    @property
    def triangle_count(self) -> int:
        return sum(g.triangles * g.count for g in self.groups)


def instance_table(geometry, mask: np.ndarray, origin=None) -> InstanceTable:
    """Pack the instances of ``geometry`` selected by ``mask`` (bool (N,)), with
    matrices relative to ``origin`` (float64 subtraction before the float32
    upload, so far-away scenes keep their precision)."""
    import gpu
    inst = geometry.instances
    idx = np.flatnonzero(mask)
    if len(idx) == 0:
        return InstanceTable(texture=None)
    mats = inst.matrices[idx].copy()
    if origin is not None:
        mats[:, :3, 3] -= np.asarray(origin, dtype=np.float64)
    mirrored = np.linalg.det(mats[:, :3, :3]) < 0
    keys = [inst.keys[i] for i in idx]
    order_keys = {}
    for k in keys:
        order_keys.setdefault(k, len(order_keys))
    sort = np.lexsort((mirrored, np.array([order_keys[k] for k in keys])))
    mats = mats[sort]
    mirrored = mirrored[sort]
    keys = [keys[i] for i in sort]
    groups = []
    start = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start] or mirrored[i] != mirrored[start]:
            k = keys[start]
            groups.append(DrawGroup(k, start, i - start, bool(mirrored[start]), geometry.meshes[k].triangle_count))
            start = i
    n = len(mats)
    rows = (n + INSTANCES_PER_ROW - 1) // INSTANCES_PER_ROW
    per_row = min(n, INSTANCES_PER_ROW)
    width = 4 * per_row
    data = np.zeros((rows * per_row, 4, 4), dtype=np.float32)
    data[:n] = mats.transpose(0, 2, 1)  # texel c of an instance = column c
    buf = gpu.types.Buffer("FLOAT", data.size, data.ravel())
    tex = gpu.types.GPUTexture((width, rows), format="RGBA32F", data=buf)
    return InstanceTable(texture=tex, groups=groups, instance_count=n)


def draw_table(shader, batches: BatchCache, geometry, table: InstanceTable, cull: str = "NONE",
               flip: bool = False) -> None:
    """Draw every group of ``table`` with ``shader`` (already bound, its other
    uniforms set). ``cull``: "NONE", "BACK" or "FRONT" faces. Counter-clockwise
    is front unless ``flip`` (a view transform that mirrors) or the group is
    mirrored, but not both."""
    import gpu
    if table.texture is None:
        return
    shader.uniform_sampler("u_instances", table.texture)
    gpu.state.face_culling_set(cull)
    for g in table.groups:
        if cull != "NONE":
            gpu.state.front_facing_set(g.mirrored != flip)
        shader.uniform_int("u_instance_offset", g.offset)
        batches.get(geometry.meshes[g.key]).draw_instanced(shader, instance_start=0, instance_count=g.count)
    gpu.state.face_culling_set("NONE")
    gpu.state.front_facing_set(False)
