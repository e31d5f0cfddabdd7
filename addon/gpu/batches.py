"""The scene on the GPU: one batch per mesh, every instance's matrix in one
texture, and per pass the list of instances it draws.

Every batch has a single ``pos`` attribute (local space, float32); instances
are drawn with ``GPUBatch.draw_instanced``. The gpu module exposes no
per-instance vertex buffers (shared notes §3), so the vertex stage fetches
its instance from textures (``gpu_shaders/instance_lib.glsl``): a draw list
(R32F, the ids of the instances a pass draws, grouped by batch and
handedness; exact below 2^24 instances) and, through the id, the instance's object -> world matrix
(RGBA32F, four texels per instance).

What is uploaded when:

* a batch when its mesh's content changed (``BatchCache``: version and fingerprint);
* the matrices when the scene's instances changed (a new ``InstanceSet``:
  a transform, visibility, an instance added or removed); the last
  ``GPUScene.KEEP_SETS`` sets stay uploaded with their draw lists, so F12's
  render depsgraph and the viewport's, used in turn, upload nothing;
* a draw list when the instances a pass draws differ from its last list
  (the camera or the light moved enough to change the culling).

A second frame of an unchanged scene and view uploads nothing; the counters
(``BatchCache.uploads``, ``GPUScene.matrix_uploads``, ``GPUScene.list_uploads``)
let tests show it.
"""
from __future__ import annotations

import functools
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


@functools.cache
def shared_batches() -> BatchCache:
    """The process-wide batch cache (lives as long as the GPU context)."""
    return BatchCache()


def _texture(fmt: str, width: int, rows: int, flat: np.ndarray):
    """A texture from float32 data (the only data type ``GPUTexture`` takes from Python)."""
    import gpu
    return gpu.types.GPUTexture((width, rows), format=fmt, data=gpu.types.Buffer("FLOAT", flat.size, flat))


@dataclass
class DrawGroup:
    """Instances of one batch with the same handedness, drawn in one call:
    ``count`` ids from ``offset`` in the draw list."""

    key: tuple
    offset: int
    count: int
    mirrored: bool
    triangles: int


@dataclass
class DrawList:
    """The instances one pass draws: their ids (an R32F texture) grouped by
    batch and handedness (a mirroring matrix flips winding, which matters
    when culling faces)."""

    texture: object
    groups: list = field(default_factory=list)
    instance_count: int = 0

    @property
    def triangle_count(self) -> int:
        return sum(g.triangles * g.count for g in self.groups)


class _Grouping:
    """The instances of a set ordered by (geometry key, handedness), made once per set."""

    def __init__(self, instances, key_triangles: np.ndarray):
        code = instances.key_ids * 2 + instances.mirrored
        self.order = np.argsort(code, kind="stable")
        sorted_code = code[self.order]
        self.starts = np.flatnonzero(np.r_[True, sorted_code[1:] != sorted_code[:-1]]) if len(code) else \
            np.zeros(0, dtype=np.int64)
        first = sorted_code[self.starts]
        self.groups = [(instances.key_list[c // 2], bool(c % 2), int(key_triangles[c // 2])) for c in first]


COMPACT_REACH = 1.0e4
"""How far from the centre of a scene's boxes they may reach for that centre to be the point the GPU draws relative
to: float32 steps there are at most COMPACT_REACH / 2^24 = 0.6 mm (:func:`drawing_origin`)."""


def drawing_origin(boxes: np.ndarray) -> np.ndarray:
    """The point the GPU draws a scene's (N, 2, 3) world ``boxes`` relative to, in float32: the centre of the boxes
    where they all lie within :data:`COMPACT_REACH` of it, else per axis the median of the boxes' centres (of the
    two middle ones, the one nearer the world origin). That point stays with the bulk of the scene, so a scene far
    from the world origin keeps its precision and an object far from the rest (a moon, a stray vertex) costs the
    rest none: the centre lies half way to it, where float32 steps are up to its distance / 2^24 (a cube 1e7 m away
    drew the scene near the world origin in 0.5 m steps; 1e9 m away, collapsed it into one point)."""
    low, high = boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)
    if np.all(high - low <= 2 * COMPACT_REACH):
        return (low + high) / 2
    centres = (boxes[:, 0] + boxes[:, 1]) / 2
    n = len(centres)
    middle = np.partition(centres, [(n - 1) // 2, n // 2], axis=0)
    low, high = middle[(n - 1) // 2], middle[n // 2]
    return np.where(np.abs(low) <= np.abs(high), low, high)


class _UploadedSet:
    """The GPU side of one InstanceSet: its matrices, its grouping, its passes' draw lists."""

    def __init__(self, geometry):
        inst = self.instances = geometry.instances
        self.geometry = geometry
        self.grouping = _Grouping(inst, geometry.key_triangles)
        self.lists: dict = {}
        self.selections: dict = {}
        self.matrices = None
        self.origin = np.zeros(3)
        n = len(inst)
        if n == 0:
            return
        self.origin = drawing_origin(inst.world_boxes())
        mats = inst.matrices.copy()
        mats[:, :3, 3] -= self.origin                      # relative in float64, then float32
        rows = -(-n // INSTANCES_PER_ROW)
        per_row = min(n, INSTANCES_PER_ROW)
        data = np.zeros((rows * per_row, 4, 4), dtype=np.float32)
        data[:n] = mats.transpose(0, 2, 1)                 # texel c of an instance = column c
        self.matrices = _texture("RGBA32F", 4 * per_row, rows, data.ravel())

    def regroup(self, geometry) -> None:
        """The same instances with other meshes (a mesh changed): new triangle counts."""
        self.geometry = geometry
        self.grouping = _Grouping(self.instances, geometry.key_triangles)
        self.lists.clear()
        self.selections.clear()


class GPUScene:
    """The GPU side of a :class:`~addon.scene.geometry.SceneGeometry`.

    ``sync(geometry)`` uploads the instance matrices when the instance set is
    a new one, relative to ``origin`` (:func:`drawing_origin`, with the bulk of the scene's boxes: the
    GPU works in float32, so scenes far from the world origin keep their
    precision; every matrix a pass uses is made relative to the same point).
    The last few instance sets stay uploaded, so the render engine's and the
    viewport's (their depsgraphs may differ) do not push each other out.
    ``draw_list(pass_name, mask)`` gives the ids of the instances selected by
    ``mask``, uploaded only when they differ from that pass's last list.
    """

    KEEP_SETS = 4
    """Instance sets kept uploaded."""

    def __init__(self, batches: BatchCache | None = None):
        self.batches = batches if batches is not None else BatchCache()
        self.geometry = None
        self.matrix_uploads = 0
        self.list_uploads = 0
        self.culls = 0
        """Culling tests run (:meth:`selection`; a kept result is not counted)."""
        self._sets: dict = {}          # id(InstanceSet) -> _UploadedSet, oldest first
        self._current: _UploadedSet | None = None

    @property
    def instances(self):
        return self._current.instances if self._current is not None else None

    @property
    def origin(self) -> np.ndarray:
        return self._current.origin if self._current is not None else np.zeros(3)

    @property
    def matrices(self):
        return self._current.matrices if self._current is not None else None

    def sync(self, geometry) -> None:
        """Make ``geometry`` the scene drawn; uploads its instance matrices if they changed."""
        if geometry is self.geometry:
            return
        self.geometry = geometry
        inst = geometry.instances
        entry = self._sets.pop(id(inst), None)
        if entry is None or entry.instances is not inst:
            entry = _UploadedSet(geometry)
            self.matrix_uploads += entry.matrices is not None
            while len(self._sets) >= self.KEEP_SETS:
                self._sets.pop(next(iter(self._sets)))
        elif entry.geometry is not geometry:
            entry.regroup(geometry)
        self._sets[id(inst)] = entry            # the most recent last
        self._current = entry

    KEEP_SELECTIONS = 24
    """Culling results kept per instance set (an F12's and a viewport's views: receivers, casters, and the
    solids the camera and each map see from outside)."""

    def selection(self, query: tuple, select) -> np.ndarray:
        """The instance mask ``select()`` gives for ``query`` (a hashable
        description of a culling test over the current instance set), kept for
        the last few queries: an unchanged view or B (an F12 again, a redraw)
        culls once. The mask is shared: read it, do not change it."""
        kept = self._current.selections
        mask = kept.pop(query, None)
        if mask is None:
            mask = select()
            self.culls += 1
            while len(kept) >= self.KEEP_SELECTIONS:
                kept.pop(next(iter(kept)))
        kept[query] = mask                       # the most recent last
        return mask

    def draw_list(self, pass_name: str, mask: np.ndarray, eye=None) -> DrawList:
        """The instances selected by ``mask`` (bool (N,)), for the pass
        ``pass_name``. ``eye``: a point the pass looks from; each group is then
        drawn nearest first (by box centre), so the depth test rejects what is
        hidden before it is shaded. A list is made again only when the
        selection changes (an order made from an earlier eye is as correct)."""
        lists = self._current.lists
        hit = lists.get(pass_name)
        if hit is not None and np.array_equal(hit[0], mask):
            return hit[1]
        g = self._current.grouping
        chosen = mask[g.order]
        ids = g.order[chosen]
        n = len(ids)
        groups = []
        if n:
            counts = np.add.reduceat(chosen, g.starts, dtype=np.int64)
            offsets = np.cumsum(counts) - counts
            if eye is not None:
                boxes = self.instances.world_boxes()[ids]
                near = ((boxes[:, 0] + boxes[:, 1]) / 2 - np.asarray(eye, dtype=np.float64)) ** 2
                group_of = np.repeat(np.arange(len(counts)), counts)
                ids = ids[np.lexsort((near.sum(axis=1), group_of))]
            for (key, mirrored, tris), c, o in zip(g.groups, counts.tolist(), offsets.tolist()):
                if c:
                    groups.append(DrawGroup(key, o, c, mirrored, tris))
        texture = None
        if n:
            rows = -(-n // INSTANCES_PER_ROW)
            per_row = min(n, INSTANCES_PER_ROW)
            flat = np.zeros(rows * per_row, dtype=np.float32)
            flat[:n] = ids                                 # exact below 2^24 instances
            texture = _texture("R32F", per_row, rows, flat)
            self.list_uploads += 1
        out = DrawList(texture, groups, n)
        lists[pass_name] = (mask.copy(), out)
        return out

    def batch(self, key):
        return self.batches.get(self.geometry.meshes[key])

    def draw(self, shader, draw_list: DrawList, cull: str = "NONE", flip: bool = False) -> None:
        """Draw ``draw_list`` with ``shader`` (already bound, its other uniforms
        set). ``cull``: "NONE", "BACK" or "FRONT" faces. Counter-clockwise is
        front unless ``flip`` (a view transform that mirrors) or the group is
        mirrored, but not both."""
        import gpu
        if draw_list.texture is None:
            return
        shader.uniform_sampler("u_instances", self.matrices)
        shader.uniform_sampler("u_ids", draw_list.texture)
        gpu.state.face_culling_set(cull)
        for g in draw_list.groups:
            if cull != "NONE":
                gpu.state.front_facing_set(g.mirrored != flip)
            shader.uniform_int("u_instance_offset", g.offset)
            self.batch(g.key).draw_instanced(shader, instance_start=0, instance_count=g.count)
        gpu.state.face_culling_set("NONE")
        gpu.state.front_facing_set(False)


_shared_scene = None


def shared_scene() -> GPUScene:
    """The process-wide GPU scene (over the process-wide batches)."""
    global _shared_scene
    if _shared_scene is None:
        _shared_scene = GPUScene(shared_batches())
    return _shared_scene
