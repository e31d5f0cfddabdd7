"""One walk over ``depsgraph.object_instances``: every drawable thing in the
evaluated scene (real objects and geometry-nodes / particle / collection
instances) as plain float64 data.

Shared by :mod:`.describe` (scene bounds) and :mod:`.geometry` (triangles), so
both see exactly the same set of instances with the same matrices.

Platform facts (shared notes §3): ``inst.matrix_world`` wraps memory valid only
for one iteration step, so it is copied at once; the evaluated object of a
geometry instance is temporary too, so anything needed from it (its geometry)
is taken inside the walk through the ``on_geometry`` callback.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT"})
"""Object types whose evaluated geometry can be turned into triangles."""


def _id_key(idb) -> str:
    lib = getattr(idb, "library", None)
    return f"{idb.name}@{lib.filepath}" if lib is not None else idb.name


def geometry_key(inst, ob, generated: dict) -> tuple:
    """The cache key of the triangles an instance draws (one batch per key).

    * A real mesh object without modifiers draws its mesh datablock:
      ``("ME", mesh name)``, shared by every object using that mesh.
    * A real object with modifiers (or a curve/text/metaball) draws geometry
      evaluated for that object: ``("OB", object name)``. Instances of real
      objects (collection instances, particles) get the same keys.
    * Geometry created inside a node tree has no datablock of its own: its
      evaluated object is a temporary copy of the generating object. It is keyed
      ``("GN", generating object, mesh name, ordinal)``, where the ordinal
      numbers the distinct meshes of that name in that object's evaluation
      order (``generated`` holds the numbering for one walk), so the key is
      stable from one evaluation to the next.
    """
    data = ob.data
    parent = inst.parent if inst.is_instance else None
    if parent is not None and ob.original == parent.original:
        uid = data.session_uid
        key = generated.get(uid)
        if key is None:
            base = ("GN", _id_key(parent.original), data.name)
            n = generated[base] = generated.get(base, -1) + 1
            key = generated[uid] = base + (n,)
        return key
    if ob.type == "MESH" and len(ob.modifiers) == 0 and data is not None and data.original is not None:
        return ("ME", _id_key(data.original))
    return ("OB", _id_key(ob.original))


@dataclass
class InstanceSet:
    """Every drawable instance of an evaluated scene.

    ``keys[i]`` names the triangles instance ``i`` draws (see :func:`geometry_key`),
    ``matrices[i]`` its object -> world matrix, ``local_boxes[i]`` its
    object-space bounding box ``[[min], [max]]``, ``casts`` whether it casts
    shadows (``visible_shadow``), ``receives`` whether the camera sees it
    (``visible_camera``), ``names[i]`` the object (for messages and counts).
    """

    keys: list = field(default_factory=list)
    names: list = field(default_factory=list)
    matrices: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    local_boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    casts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    receives: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def __len__(self) -> int:
        return len(self.keys)

    def world_boxes(self) -> np.ndarray:
        """(N, 2, 3) world-space AABBs of the instances' local boxes."""
        return transform_boxes(self.matrices, self.local_boxes)


def transform_boxes(matrices: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """World AABBs of (N, 2, 3) local boxes under (N, 4, 4) affine matrices
    (Arvo's method: centre and half-extent through |M|)."""
    if len(boxes) == 0:
        return np.zeros((0, 2, 3))
    centre = (boxes[:, 0] + boxes[:, 1]) / 2
    half = (boxes[:, 1] - boxes[:, 0]) / 2
    lin = matrices[:, :3, :3]
    c = np.einsum("nij,nj->ni", lin, centre) + matrices[:, :3, 3]
    h = np.einsum("nij,nj->ni", np.abs(lin), half)
    return np.stack([c - h, c + h], axis=1)


def walk_instances(depsgraph, on_geometry: Optional[Callable] = None) -> InstanceSet:
    """Walk the evaluated scene once.

    ``on_geometry(key, ob_eval)`` is called the first time each geometry key is
    met, while the evaluated object is still valid; it may return False to
    drop every instance of that key (e.g. a mesh with no faces).
    """
    keys, names, casts, receives = [], [], [], []
    mats = np.empty((256, 4, 4), dtype=np.float64)
    accepted: dict = {}   # key -> None (dropped) or its object-space box
    generated: dict = {}
    n = 0
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob is None or ob.type not in GEOMETRY_TYPES:
            continue
        if not inst.is_instance and not inst.show_self:
            continue  # an instancer that hides itself (e.g. a particle emitter)
        if ob.type == "MESH" and len(ob.data.polygons) == 0:
            continue  # nothing to draw (e.g. a node tree that outputs only instances)
        key = geometry_key(inst, ob, generated)
        if key not in accepted:
            ok = True if on_geometry is None else bool(on_geometry(key, ob))
            if ok:
                bb = np.array(ob.bound_box, dtype=np.float64)
                accepted[key] = (bb.min(axis=0), bb.max(axis=0))
            else:
                accepted[key] = None
        if accepted[key] is None:
            continue
        if n == len(mats):
            mats = np.concatenate([mats, np.empty_like(mats)])
        mats[n] = inst.matrix_world  # copied now: the Matrix is only valid during this step
        n += 1
        keys.append(key)
        names.append(ob.name if not inst.is_instance or inst.parent is None else f"{inst.parent.name}/{ob.name}")
        casts.append(bool(getattr(ob, "visible_shadow", True)))
        receives.append(bool(getattr(ob, "visible_camera", True)))
    if not keys:
        return InstanceSet()
    boxes = np.array([accepted[k] for k in keys], dtype=np.float64).reshape(-1, 2, 3)
    return InstanceSet(
        keys=keys,
        names=names,
        matrices=mats[:n].copy(),
        local_boxes=boxes,
        casts=np.asarray(casts, dtype=bool),
        receives=np.asarray(receives, dtype=bool),
    )
