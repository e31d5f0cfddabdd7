"""Triangles of the evaluated scene, one :class:`MeshData` per mesh datablock,
kept across renders by :class:`GeometryCache`.

Fast paths (shared notes §3): positions through
``attributes['position'].data.foreach_get('vector')`` and corners through the
``.corner_vert`` attribute (both about 1 ms per million); triangles and quads
are triangulated in numpy (``loop_triangles.foreach_get`` costs ~100 ms per
million triangles and is used only for meshes with n-gons). Instance matrices
are copied during the walk (``.copy()`` rule, see :mod:`.instances`).

Cache rule: a mesh is re-extracted (triangulated, and its batch re-uploaded,
see ``addon.gpu.batches``) only when its content fingerprint (sizes + CRC of
positions and corners, ~3 ms per million vertices) changed; an unchanged one
costs the reads and the CRC (1M triangles: 3.3 ms, against 46 ms when it was
triangulated again before the comparison).
``depsgraph.updates`` alone cannot decide it (measured, 4.2 and 5.0): a fresh
render depsgraph (every F12 without persistent data) flags every object as
updated, and outside ``depsgraph_update_post`` handlers and
``RenderEngine.view_update`` the collection is empty even after edits. Callers
that do see a complete update list (those two places) pass
``trust_updates=True``: unflagged meshes are then reused without even a
fingerprint.
"""
from __future__ import annotations

import logging
import zlib
from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

import numpy as np

from .instances import InstanceSet, scene_instances

log = logging.getLogger(__name__)


@dataclass
class MeshData:
    """Local-space triangles of one geometry key: ``positions`` (V, 3) float32,
    ``triangles`` (T, 3) int32. ``version`` increases whenever the content changes."""

    key: tuple
    positions: np.ndarray
    triangles: np.ndarray
    fingerprint: tuple = ()
    version: int = 0
    settled: bool = True
    """False for a mesh re-read with new content (an edit, or an animated
    deformation) until an update finds it unchanged: while it is being edited it
    is drawn whole (:attr:`bounds_solids` is False, which is always right, only
    less culled), and its closedness test waits until the edits stop
    (``GeometryCache(defer_solids=True)``, the default; ``python -m bench.closed_edit``)."""

    @property
    def triangle_count(self) -> int:
        return len(self.triangles)

    @cached_property
    def closed_parts(self) -> Optional[np.ndarray]:
        """Each triangle's connected part (the least vertex index in it) if
        every edge is shared by exactly two triangles wound opposite ways (a
        closed, consistently oriented surface), else None. One sort: an edge
        a -> b and its twin b -> a get the same code but for the last bit, so
        sorted, the codes pair up as (even, even + 1) (a degenerate side a -> a
        has no twin: such a mesh is drawn whole). It depends on the
        triangles alone: a mesh whose vertices moved keeps it
        (:meth:`keep_closed_parts_of`)."""
        t = self.triangles
        a, b = t.ravel(), t[:, [1, 2, 0]].ravel()                              # each edge a -> b
        lo, hi = np.minimum(a, b).astype(np.int64), np.maximum(a, b)
        code = np.sort((lo * len(self.positions) + hi) * 2 + (a > b))
        if len(t) == 0 or len(code) % 2 or np.any(code[0::2] & 1) or np.any(code[1::2] != code[0::2] + 1):
            return None
        return _parts(t, len(self.positions))[t[:, 0]]

    def keep_closed_parts_of(self, old: "MeshData") -> None:
        """Take ``old``'s :attr:`closed_parts`, where it has them, if the
        triangles are the same (an edit that moved vertices only: in the
        viewport a mesh is re-read on every edit)."""
        if "closed_parts" in old.__dict__ and np.array_equal(old.triangles, self.triangles):
            self.__dict__["closed_parts"] = old.__dict__["closed_parts"]

    @property
    def bounds_solids(self) -> bool:
        """Whether the triangles bound solids with their normals outwards
        (:attr:`encloses_solids`), once the mesh has :attr:`settled`; False while it is edited."""
        return self.settled and self.encloses_solids

    @cached_property
    def encloses_solids(self) -> bool:
        """Whether the triangles bound solids with their normals outwards: the
        surface is closed and consistently oriented (:attr:`closed_parts`), and
        each connected part encloses a positive volume (an inside-out part
        does not). From a point outside such a mesh every ray meets one of its
        front faces before any of its back faces, so a camera that sees it
        from outside may cull its back faces
        (``addon.gpu.pipeline.ShadowFrame.camera_prepass``). Made once per
        mesh content (this object)."""
        part = self.closed_parts
        if part is None:
            return False
        n = len(self.positions)
        p = self.positions.astype(np.float64)
        p -= p.mean(axis=0)
        x, y, z = (c[self.triangles] for c in p.T)                              # (T, 3 corners) each
        # Gauss: each triangle's signed volume down to z = 0, its mean z times its area seen from +z
        area_xy = ((x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])) / 2
        volume = z.mean(axis=1) * area_xy
        used = np.zeros(n, dtype=bool)
        used[part] = True
        volumes = np.bincount(part, weights=volume, minlength=n)[used]
        rounding = np.bincount(part, weights=np.abs(volume), minlength=n)[used] * 1e-9
        return bool(np.all(volumes > rounding))


def _parts(triangles: np.ndarray, vertex_count: int) -> np.ndarray:
    """Each vertex's connected part (the least vertex index in it), joined by
    two sides of each triangle (they join its three corners): the greater
    root of each side whose ends differ is hooked under the lesser, then
    every vertex pointed at its root, until every side joins one part. A
    side once joined stays joined, so each round looks at those that were
    not."""
    a, b = np.repeat(triangles[:, 0], 2), triangles[:, 1:].ravel()
    label = np.arange(vertex_count)
    while True:
        la, lb = label[a], label[b]
        apart = la != lb
        if not apart.any():
            return label
        a, b, la, lb = a[apart], b[apart], la[apart], lb[apart]
        label[np.maximum(la, lb)] = np.minimum(la, lb)      # roots only point lower: no cycle
        while True:
            root = label[label]
            if np.array_equal(root, label):
                break
            label = root


@dataclass(eq=False)
class SceneGeometry:
    """What the gpu pipeline draws: every instance and the meshes they use.
    Never changed once made (a cache hands out the same object while the scene
    is unchanged)."""

    instances: InstanceSet
    meshes: dict = field(default_factory=dict)

    @property
    def triangle_count(self) -> int:
        """Triangles over all instances."""
        return int(self.key_triangles[self.instances.key_ids].sum())

    @cached_property
    def key_triangles(self) -> np.ndarray:
        """Triangles of each of ``instances.key_list``."""
        return np.array([self.meshes[k].triangle_count for k in self.instances.key_list], dtype=np.int64)

    @classmethod
    def from_arrays(cls, parts) -> "SceneGeometry":
        """Geometry without bpy objects (tests, benchmarks): ``parts`` is a list of
        ``(name, positions (V,3), triangles (T,3), matrices (N,4,4) or None,
        casts=True, holdout=False)`` tuples; each part becomes one mesh drawn once per matrix."""
        meshes, keys, mats, boxes, casts, holdouts = {}, [], [], {}, [], []
        for part in parts:
            name, pos, tris, m = part[:4]
            cast = part[4] if len(part) > 4 else True
            key = ("ARRAY", name)
            pos = np.asarray(pos, dtype=np.float32).reshape(-1, 3)
            tris = np.asarray(tris, dtype=np.int32).reshape(-1, 3)
            meshes[key] = MeshData(key, pos, tris, fingerprint=_fingerprint(pos, tris), version=1)
            m = np.eye(4)[None] if m is None else np.asarray(m, dtype=np.float64).reshape(-1, 4, 4)
            boxes[key] = np.array([pos.min(axis=0), pos.max(axis=0)], dtype=np.float64)
            keys += [key] * len(m)
            mats.append(m)
            casts += [bool(cast)] * len(m)
            holdouts += [bool(part[5]) if len(part) > 5 else False] * len(m)
        inst = InstanceSet.from_lists(keys, np.concatenate(mats) if mats else np.zeros((0, 4, 4)), boxes, casts,
                                      np.ones(len(keys), dtype=bool), holdouts=holdouts)
        return cls(inst, meshes)


def _fingerprint(*arrays) -> tuple:
    return tuple((a.shape, zlib.crc32(np.ascontiguousarray(a))) for a in arrays)


def _quads_and_tris(positions: np.ndarray, starts: np.ndarray, sizes: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Triangles of a mesh whose faces all have 3 or 4 corners (numpy).

    A quad is split along its 0-2 diagonal unless that makes the two triangles
    face opposite ways (a concave quad), in which case the 1-3 diagonal is
    used, the one through the reflex corner.
    """
    tri = sizes == 3
    quad = ~tri
    out = []
    if tri.any():
        s = starts[tri]
        out.append(np.stack([corners[s], corners[s + 1], corners[s + 2]], axis=1))
    if quad.any():
        s = starts[quad]
        a, b, c, d = corners[s], corners[s + 1], corners[s + 2], corners[s + 3]
        pa = positions[a]
        ac = positions[c] - pa
        with np.errstate(over="ignore", invalid="ignore"):  # a NaN/inf vertex: refused later, by name
            n1 = np.cross(positions[b] - pa, ac)
            n2 = np.cross(ac, positions[d] - pa)
            flip = np.einsum("ij,ij->i", n1, n2) < 0  # float32 is plenty for a sign
        t1 = np.stack([a, b, c], axis=1)
        t2 = np.stack([a, c, d], axis=1)
        if flip.any():
            t1[flip] = np.stack([b[flip], c[flip], d[flip]], axis=1)
            t2[flip] = np.stack([b[flip], d[flip], a[flip]], axis=1)
        out += [t1, t2]
    if not out:
        return np.zeros((0, 3), np.int32)
    return np.ascontiguousarray(np.concatenate(out), dtype=np.int32)


def read_mesh(mesh, known: tuple = ()) -> tuple[np.ndarray, Optional[np.ndarray], tuple]:
    """(positions float32 (V,3), triangles int32 (T,3), fingerprint) of a Mesh; the
    triangles are None when the fingerprint is ``known`` (the caller has them: an
    unchanged mesh is not triangulated again, 22-35 ms for a mesh of 250k quads)."""
    nv = len(mesh.vertices)
    pos = np.empty(nv * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", pos)
    pos = pos.reshape(-1, 3)
    nl = len(mesh.loops)
    corners = np.empty(nl, dtype=np.int32)
    cv = mesh.attributes.get(".corner_vert")
    if cv is not None:
        cv.data.foreach_get("value", corners)
    else:
        mesh.loops.foreach_get("vertex_index", corners)
    npoly = len(mesh.polygons)
    fp = _fingerprint(pos, corners) + ((nv, nl, npoly),)
    if fp == known:
        return pos, None, fp
    if nl == 3 * npoly:
        return pos, corners.reshape(-1, 3).copy(), fp
    starts = np.empty(npoly, dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    sizes = np.diff(np.append(starts, nl))
    if np.all(np.diff(starts) > 0) and sizes.max(initial=3) <= 4 and sizes.min(initial=3) >= 3:
        return pos, _quads_and_tris(pos, starts, sizes, corners), fp
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return pos, tris.reshape(-1, 3), fp


def read_object(ob_eval, known: tuple = ()) -> Optional[tuple[np.ndarray, Optional[np.ndarray], tuple]]:
    """Triangles of an evaluated object (mesh, curve, text, metaball; a mesh in Edit Mode), or None
    if it has no faces (``known``: see :func:`read_mesh`)."""
    if ob_eval.type == "MESH" and not ob_eval.data.is_editmode:   # in Edit Mode: to_mesh (instances.shows_no_faces)
        mesh = ob_eval.data
        return read_mesh(mesh, known) if len(mesh.polygons) else None
    try:
        mesh = ob_eval.to_mesh()
    except RuntimeError:
        return None
    try:
        return read_mesh(mesh, known) if mesh is not None and len(mesh.polygons) else None
    finally:
        ob_eval.to_mesh_clear()


def _flagged_names(depsgraph) -> set:
    """Names of objects and data whose geometry the depsgraph reports as updated."""
    names = set()
    for u in depsgraph.updates:
        if not u.is_updated_geometry:
            continue
        idb = getattr(u.id, "original", None) or u.id
        names.add(idb.name)
        data = getattr(idb, "data", None)
        if data is not None:
            names.add(data.name)
    return names


class GeometryCache:
    """The scene's instances and meshes, kept across renders.

    ``update(depsgraph)`` reads the evaluated scene (:func:`.instances.scene_instances`:
    arrays on Blender 4.3+, the walk before) and returns a :class:`SceneGeometry`.
    Only what changed is redone:

    * a mesh is re-read only when its content changed (its fingerprint; or,
      with ``trust_updates``, when the depsgraph flags it);
    * when every instance (keys, matrices, visibility) and every mesh is as
      last time, the same ``SceneGeometry`` and ``InstanceSet`` objects are
      returned, so what hangs on them (the scene bounds and their culling
      index, the GPU's instance matrices) is not rebuilt.

    ``defer_solids``: a mesh re-read with new content is not :attr:`MeshData.settled`
    until an update finds it unchanged (its closedness test, 1M triangles: 134-144 ms
    after a topology edit, 41-47 ms after a vertex move, waits until the edits stop).

    Counters: ``extractions`` meshes (re-)read, ``reused`` meshes taken as they
    were, ``instance_sets`` new instance sets made (the scene's instances changed).
    """

    KEEP_UNUSED = 8
    """Updates a mesh may go unused before it is forgotten."""

    def __init__(self, defer_solids: bool = True):
        self.defer_solids = defer_solids
        self.meshes: dict = {}
        self.extractions = 0
        self.reused = 0
        self.instance_sets = 0
        self._last_depsgraph = None
        self._generation = 0
        self._last_used: dict = {}
        self._last: dict = {}
        """(scene, view layer, depsgraph mode, exclude) -> the last SceneGeometry handed out for it:
        the render engine's depsgraph and the viewport's may differ (objects hidden in one), and
        alternating between them must not rebuild either's instance set."""

    def clear(self) -> None:
        self.meshes.clear()
        self._last_used.clear()
        self._last_depsgraph = None
        self._last.clear()

    def update(self, depsgraph, exclude=None, trust_updates: bool = False) -> SceneGeometry:
        """Read ``depsgraph`` and return its geometry; ``exclude(ob_eval)`` -> True
        leaves an object out (e.g. Lixel's own debug objects). ``trust_updates``:
        ``depsgraph.updates`` lists every change since the last call with this
        depsgraph (see the module docstring)."""
        same_graph = trust_updates and self._last_depsgraph == depsgraph.as_pointer()
        flagged = _flagged_names(depsgraph) if same_graph else set()
        used: dict = {}

        def on_geometry(key, ob, mesh=None):
            if exclude is not None and exclude(ob):
                return False
            old = self.meshes.get(key)
            if old is not None and same_graph and key[1].split("@")[0] not in flagged:
                used[key] = old
                old.settled = True
                self.reused += 1
                return True
            known = old.fingerprint if old is not None else ()
            got = read_mesh(mesh, known) if mesh is not None else read_object(ob, known)
            if got is None:
                return False
            pos, tris, fp = got
            if old is not None and old.fingerprint == fp:
                used[key] = old
                old.settled = True
                self.reused += 1
                return True
            if len(tris) == 0:
                return False
            self.extractions += 1
            used[key] = made = MeshData(key, pos, tris, fp, version=(old.version + 1) if old is not None else 1,
                                        settled=old is None or not self.defer_solids)
            if old is not None:
                made.keep_closed_parts_of(old)
            return True

        scene = depsgraph.scene
        slot = (getattr(scene, "name", ""), getattr(depsgraph.view_layer, "name", ""), depsgraph.mode, exclude)
        last = self._last.get(slot)
        instances = scene_instances(depsgraph, on_geometry, last.instances if last is not None else None)
        # Keep entries of objects not drawn this time (hidden, another scene) for a
        # while, then forget them (deleted objects must not pin memory).
        self._generation += 1
        for k in used:
            self._last_used[k] = self._generation
        self.meshes.update(used)
        for k in [k for k, g in self._last_used.items() if self._generation - g > self.KEEP_UNUSED]:
            del self._last_used[k]
            self.meshes.pop(k, None)
        self._last_depsgraph = depsgraph.as_pointer()
        if last is not None and last.meshes.keys() == used.keys() and \
                all(last.meshes[k] is m for k, m in used.items()) and instances.same_as(last.instances):
            return last
        if last is not None and instances.same_as(last.instances):
            instances = last.instances
        else:
            self.instance_sets += 1
        if len(self._last) >= 8 and slot not in self._last:
            self._last.pop(next(iter(self._last)))
        self._last[slot] = out = SceneGeometry(instances, used)
        return out


_shared_cache: Optional[GeometryCache] = None


def shared_cache() -> GeometryCache:
    """The process-wide geometry cache (the render engine and operators share it)."""
    global _shared_cache
    if _shared_cache is None:
        _shared_cache = GeometryCache()
    return _shared_cache
