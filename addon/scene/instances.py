"""Every drawable thing in the evaluated scene (real objects and geometry-nodes
/ particle / collection instances) as plain float64 arrays: an
:class:`InstanceSet`.

Two readers give the same set:

* :func:`read_instances` (Blender 4.3+): the evaluated objects, and for each
  geometry-nodes instancer its instances as arrays, through
  ``evaluated_geometry().instances_pointcloud()`` (``instance_transform``
  and ``.reference_index`` with ``foreach_get``: about 1 ms per 80k
  instances, against 100-270 ms for a Python walk that copies each matrix).
  It returns None where it cannot say the same as the walk (particle systems,
  dupli-verts/faces, collection instances, collections in a node tree), and
  the caller walks instead.
* :func:`walk_instances`: one walk over ``depsgraph.object_instances``
  (every version, every kind of instance).

Shared by :mod:`.describe` (scene bounds) and :mod:`.geometry` (triangles).

Platform facts (shared notes §3): ``inst.matrix_world`` wraps memory valid only
for one iteration step, so it is copied at once; the evaluated object of a
geometry instance is temporary too, so anything needed from it (its geometry)
is taken inside the walk through the ``on_geometry`` callback.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable, Optional

import numpy as np

GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT"})
"""Object types whose evaluated geometry can be turned into triangles."""
INSTANCER_TYPES = GEOMETRY_TYPES | {"CURVES", "POINTCLOUD", "VOLUME"}
"""Object types a geometry-nodes modifier can make instances on."""


def shows_no_faces(ob) -> bool:
    """Whether the evaluated object ``ob`` is a mesh with no faces to draw (a node tree that outputs only instances,
    a mesh of edges). A mesh in Edit Mode is read through ``Object.to_mesh()`` (``geometry.read_object``): its
    evaluated mesh wraps the edit mesh, whose faces (none without modifiers) and positions (none with them) the
    Python API does not show."""
    return ob.type == "MESH" and not ob.data.is_editmode and len(ob.data.polygons) == 0


def _id_key(idb) -> str:
    lib = getattr(idb, "library", None)
    return f"{idb.name}@{lib.filepath}" if lib is not None else idb.name


def object_key(ob) -> tuple:
    """The cache key of a real object's own evaluated geometry (see :func:`geometry_key`)."""
    data = ob.data
    if ob.type == "MESH" and len(ob.modifiers) == 0 and data is not None and data.original is not None:
        return ("ME", _id_key(data.original))
    return ("OB", _id_key(ob.original))


def generated_key(instancer, mesh, generated: dict) -> tuple:
    """The key of a mesh made inside ``instancer``'s node tree (see :func:`geometry_key`)."""
    uid = mesh.session_uid
    key = generated.get(uid)
    if key is None:
        base = ("GN", _id_key(instancer.original), mesh.name)
        n = generated[base] = generated.get(base, -1) + 1
        key = generated[uid] = base + (n,)
    return key


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
    parent = inst.parent if inst.is_instance else None
    if parent is not None and ob.original == parent.original:
        return generated_key(parent, ob.data, generated)
    return object_key(ob)


@dataclass(eq=False)
class InstanceSet:
    """Every drawable instance of an evaluated scene, as arrays.

    Instance ``i`` draws the triangles of ``key_list[key_ids[i]]`` (see
    :func:`geometry_key`) with the object -> world matrix ``matrices[i]``;
    ``key_boxes[k]`` is key ``k``'s object-space bounding box ``[[min],
    [max]]``; ``casts[i]`` whether it casts shadows (``visible_shadow``),
    ``receives[i]`` whether the camera sees it (``visible_camera``);
    ``holdouts[i]`` whether the view layer holds it out (:func:`holdout_test`: drawn as a transparent hole that
    still hides what is behind it and still casts its shadow);
    ``owners[owner_ids[i]]`` names its object (for messages);
    ``linkers[i]`` the original objects whose membership of a light's Light/Shadow Linking collection decides
    whether that light lights it and is blocked by it (:mod:`.linking`): (its instancer or 0, its own object or 0)
    as ``as_pointer()`` values, recorded only where a light in the scene has linking (else no rows).

    A set is never changed once made: what is derived from it (world boxes,
    the :class:`SceneBounds` with its culling index) is computed once, and a
    cache that finds the scene unchanged hands out the same set again.
    """

    key_list: list = field(default_factory=list)
    key_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    matrices: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    key_boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    casts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    receives: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    holdouts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    linkers: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    owners: list = field(default_factory=list)
    owner_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @classmethod
    def from_lists(cls, keys: list, matrices, boxes: dict, casts, receives, names: Optional[list] = None,
                   holdouts=None, linkers=None) -> "InstanceSet":
        """A set from per-instance keys (with ``boxes[key]`` each key's local box); ``holdouts`` default none,
        ``linkers`` none recorded."""
        key_list: list = []
        index: dict = {}
        ids = np.fromiter((index.setdefault(k, len(index)) for k in keys), dtype=np.int64, count=len(keys))
        key_list = list(index)
        names = names if names is not None else [k[1] for k in keys]
        owner_index: dict = {}
        owner_ids = np.fromiter((owner_index.setdefault(n, len(owner_index)) for n in names), dtype=np.int64,
                                count=len(names))
        return cls(key_list=key_list, key_ids=ids,
                   matrices=np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4),
                   key_boxes=np.array([boxes[k] for k in key_list], dtype=np.float64).reshape(-1, 2, 3),
                   casts=np.asarray(casts, dtype=bool), receives=np.asarray(receives, dtype=bool),
                   holdouts=np.zeros(len(keys), dtype=bool) if holdouts is None else np.asarray(holdouts, dtype=bool),
                   linkers=np.zeros((0, 2), dtype=np.int64) if linkers is None else
                   np.asarray(linkers, dtype=np.int64).reshape(-1, 2),
                   owners=list(owner_index), owner_ids=owner_ids)

    def __len__(self) -> int:
        return len(self.key_ids)

    @property
    def keys(self) -> list:
        """Each instance's geometry key (a list; prefer ``key_ids`` in bulk code)."""
        return [self.key_list[i] for i in self.key_ids]

    @property
    def names(self) -> list:
        return [self.owners[i] for i in self.owner_ids]

    @property
    def local_boxes(self) -> np.ndarray:
        """(N, 2, 3) object-space box of each instance."""
        return self.key_boxes[self.key_ids]

    @cached_property
    def world_box_array(self) -> np.ndarray:
        box = transform_boxes(self.matrices, self.local_boxes)
        box.flags.writeable = False
        return box

    def world_boxes(self) -> np.ndarray:
        """(N, 2, 3) world-space AABBs of the instances' local boxes."""
        return self.world_box_array

    @cached_property
    def bounds(self):
        """The :class:`SceneBounds` of these instances (casters, receivers),
        made once: its culling indices are built once per instance set."""
        from ..warp.types import SceneBounds
        boxes = self.world_boxes()
        if self.casts.all() and self.receives.all():
            return SceneBounds(boxes, boxes, solid=False)
        return SceneBounds(boxes[self.casts], boxes[self.receives], solid=False)

    @cached_property
    def caster_ids(self) -> np.ndarray:
        """Instance index of each of ``bounds.casters``."""
        return np.flatnonzero(self.casts)

    @cached_property
    def receiver_ids(self) -> np.ndarray:
        """Instance index of each of ``bounds.receivers``."""
        return np.flatnonzero(self.receives)

    @cached_property
    def any_holdout(self) -> bool:
        """Whether any instance is held out (a frame without holdouts draws as it did before they were supported)."""
        return bool(self.holdouts.any())

    @cached_property
    def mirrored(self) -> np.ndarray:
        """Whether each matrix mirrors (negative determinant: winding flips)."""
        return np.linalg.det(self.matrices[:, :3, :3]) < 0

    def same_as(self, other: Optional["InstanceSet"]) -> bool:
        """Whether ``other`` holds the same instances (keys, matrices, visibility)."""
        if other is self:
            return True
        return (other is not None and self.key_list == other.key_list
                and np.array_equal(self.key_ids, other.key_ids)
                and np.array_equal(self.casts, other.casts) and np.array_equal(self.receives, other.receives)
                and np.array_equal(self.holdouts, other.holdouts) and np.array_equal(self.linkers, other.linkers)
                and np.array_equal(self.matrices, other.matrices)
                and np.array_equal(self.key_boxes, other.key_boxes))


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


def _local_box(ob) -> tuple:
    bb = np.array(ob.bound_box, dtype=np.float64)
    return bb.min(axis=0), bb.max(axis=0)


def _mesh_box(mesh) -> tuple:
    n = len(mesh.vertices)
    pos = np.empty(n * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", pos)
    pos = pos.reshape(-1, 3)
    return pos.min(axis=0).astype(np.float64), pos.max(axis=0).astype(np.float64)


def _flagged_layer_collections(layer, flag: str) -> bool:
    """Whether ``layer`` (a LayerCollection) or one of its children has ``flag`` on (View Layer > Holdout or
    Indirect Only)."""
    return any(getattr(lc, flag) or _flagged_layer_collections(lc, flag) for lc in layer.children)


def _layer_test(depsgraph, flag: str, own: Callable) -> Optional[Callable]:
    """``test(ob) -> bool``: the view layer's answer for ``flag`` (Blender's ``Object.<flag>_get``, which needs the
    original object and a look-up in the view layer), or ``own(ob)`` where no collection of the layer has the flag
    (None where ``own`` is None: nothing has it, no work per object)."""
    scene = depsgraph.scene.original if depsgraph.scene.is_evaluated else depsgraph.scene
    view_layer = scene.view_layers.get(depsgraph.view_layer.name)
    if view_layer is None or not _flagged_layer_collections(view_layer.layer_collection, flag):
        return own
    own = own or (lambda ob: False)

    def test(ob) -> bool:
        try:
            return bool(getattr(ob.original, f"{flag}_get")(view_layer=view_layer))
        except (RuntimeError, ReferenceError):   # not in the view layer: nothing of the layer flags it
            return own(ob)
    return test


def holdout_test(depsgraph) -> Callable:
    """``held(ob) -> bool``: whether the render of ``depsgraph`` holds out the evaluated object ``ob`` (Object
    properties > Visibility > Holdout, or a collection's Holdout in the view layer; a surface whose materials are all
    a Holdout shader is held out too, per geometry: :mod:`.materials`), as Blender's
    ``Object.holdout_get`` answers it for the view layer, which Cycles reads. An instance takes its instancer's
    answer (measured with Cycles in 4.2.23 and 5.0.1: a collection instance or geometry-nodes instances of a held-out
    instancer are held out; a held-out object instanced by a plain instancer, or a collection held out in the view
    layer and instanced elsewhere, is not). Without any collection held out an object's own flag answers."""
    return _layer_test(depsgraph, "holdout", lambda ob: bool(getattr(ob, "is_holdout", False)))


def indirect_only_test(depsgraph) -> Optional[Callable]:
    """``indirect(ob) -> bool``: whether ``ob`` is in a collection the view layer renders Indirect Only, which Cycles
    hides from the camera alone (measured in 4.2.23 and 5.0.1: such a cube's pixels render as with its Ray
    Visibility > Camera off, the ground behind it shadowed by it); an instance takes its instancer's answer, as for
    holdouts. None where no collection of the view layer is Indirect Only."""
    return _layer_test(depsgraph, "indirect_only", None)


def _seen(ob, parent, indirect, indirect_by: dict) -> tuple[bool, bool]:
    """(casts, seen by the camera) of an instance of ``ob`` made by ``parent`` (None for a real object): Cycles
    ANDs an instancer's Ray Visibility with its instances' own ("visibility is inherited"; measured in 4.2.23 and
    5.0.1: Shadow or Camera off on an empty instancing a collection, or on a geometry-nodes instancer, acts as on
    the instanced object), and hides an Indirect Only instancer's instances from the camera (``indirect``)."""
    casts, camera = _flags(ob)
    if parent is not None:
        p_casts, p_camera = _flags(parent)
        casts, camera = casts and p_casts, camera and p_camera
    if camera and indirect is not None:
        owner = parent if parent is not None else ob
        pointer = owner.original.as_pointer()
        if pointer not in indirect_by:
            indirect_by[pointer] = indirect(owner)
        camera = not indirect_by[pointer]
    return casts, camera


def light_linked(depsgraph) -> bool:
    """Whether a light of ``depsgraph`` has Light or Shadow Linking (Object properties > Shading, Blender 4.0+):
    only then do the readers record each instance's ``linkers`` (one pass over the objects, no work per instance)."""
    for ob in depsgraph.objects:
        if ob.type == "LIGHT":
            links = getattr(ob, "light_linking", None)
            if links is not None and (links.receiver_collection is not None or links.blocker_collection is not None):
                return True
    return False


def linkers_of(inst, ob) -> tuple[int, int]:
    """An instance's ``InstanceSet.linkers`` row: a real object is linked as itself; an instance of a real object
    that a collection instance (or dupli-verts/faces) makes is linked as itself and, where it is not in the
    collection, as its instancer; anything else an instancer makes (geometry nodes, particles) as its instancer
    alone (measured with Cycles in 4.2.23 and 5.0.1: geometry-nodes instances of an object in the collection do not
    follow that object's state)."""
    parent = inst.parent if inst.is_instance else None
    if parent is None:
        return 0, ob.original.as_pointer()
    own = ob.original.as_pointer() if parent.instance_type in ("COLLECTION", "VERTS", "FACES") else 0
    return parent.original.as_pointer(), own


def walk_instances(depsgraph, on_geometry: Optional[Callable] = None) -> InstanceSet:
    """Walk the evaluated scene once (``depsgraph.object_instances``).

    ``on_geometry(key, ob_eval)`` is called the first time each geometry key is
    met, while the evaluated object is still valid; it may return False to
    drop every instance of that key (e.g. a mesh with no faces).
    """
    from .materials import any_holdout_material, surface_held_out
    keys, names, casts, receives, holdouts = [], [], [], [], []
    held, held_by = holdout_test(depsgraph), {}
    indirect, indirect_by = indirect_only_test(depsgraph), {}
    surfaces = {} if any_holdout_material() else None   # key -> whether its materials hold it out
    if not any(held(ob) for ob in depsgraph.objects):   # (an instance is held out by a real object, its instancer)
        held = None                                     # nothing held out: no work per instance
    linkers = [] if light_linked(depsgraph) else None
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
        if shows_no_faces(ob):
            continue  # nothing to draw (e.g. a node tree that outputs only instances)
        key = geometry_key(inst, ob, generated)
        if key not in accepted:
            ok = True if on_geometry is None else bool(on_geometry(key, ob))
            accepted[key] = _local_box(ob) if ok else None
        if accepted[key] is None:
            continue
        if n == len(mats):
            mats = np.concatenate([mats, np.empty_like(mats)])
        mats[n] = inst.matrix_world  # copied now: the Matrix is only valid during this step
        n += 1
        keys.append(key)
        names.append(ob.name if not inst.is_instance or inst.parent is None else f"{inst.parent.name}/{ob.name}")
        shadow, camera = _seen(ob, inst.parent if inst.is_instance else None, indirect, indirect_by)
        casts.append(shadow)
        receives.append(camera)
        if linkers is not None:
            linkers.append(linkers_of(inst, ob))
        if surfaces is not None and key not in surfaces:
            surfaces[key] = surface_held_out(ob)
        surface = surfaces is not None and surfaces[key]
        if held is None:
            holdouts.append(surface)
            continue
        owner = inst.parent if inst.is_instance and inst.parent is not None else ob
        pointer = owner.original.as_pointer()
        if pointer not in held_by:
            held_by[pointer] = held(owner)
        holdouts.append(held_by[pointer] or surface)
    if not keys:
        return InstanceSet()
    return InstanceSet.from_lists(keys, mats[:n], accepted, casts, receives, names, holdouts, linkers)


class _NeedsWalk(Exception):
    """Something :func:`read_instances` does not read the way the walk does."""


def _flags(ob) -> tuple[bool, bool]:
    return bool(getattr(ob, "visible_shadow", True)), bool(getattr(ob, "visible_camera", True))


def _has_nodes(ob) -> bool:
    return any(m.type == "NODES" for m in ob.modifiers)


class _Reader:
    """State of one :func:`read_instances` call.

    Instances are gathered as chunks (a key id, visibility, owner and where
    their matrices come from) over the raw arrays read from Blender (an
    object's world matrix; an instancer's world matrix, instance transforms
    and reference indices). When every raw array equals the previous read's,
    the previous :class:`InstanceSet` is the answer and no matrix is made;
    otherwise the chunks' matrices are composed and concatenated once.
    """

    def __init__(self, depsgraph, on_geometry):
        self.depsgraph = depsgraph
        self.on_geometry = on_geometry
        self.accepted: dict = {}      # key -> index in key_list, or None (dropped)
        self.key_list: list = []
        self.boxes: list = []
        self.generated: dict = {}
        self.owners: list = []
        self.sources: list = []       # raw arrays: (world,) or (world, column-major transforms, reference index)
        self.chunks: list = []        # (key id, flags, owner id, source index, reference or None, local or None,
        self.held = holdout_test(depsgraph)   #  linkers or None: see linkers_of)
        self.indirect, self.indirect_by = indirect_only_test(depsgraph), {}
        self.linked = light_linked(depsgraph)
        from .materials import any_holdout_material
        self.surfaces = any_holdout_material()

    def surface_held(self, ob, mesh=None) -> bool:
        """Whether ``ob``'s materials (``mesh``'s, for geometry-nodes geometry) hold its surface out."""
        from .materials import surface_held_out
        return self.surfaces and surface_held_out(ob, mesh)

    def key_id(self, key, ob, mesh=None) -> Optional[int]:
        k = self.accepted.get(key, -1)
        if k != -1:
            return k
        ok = True if self.on_geometry is None else bool(self.on_geometry(key, ob, mesh))
        if ok:
            k = len(self.key_list)
            self.key_list.append(key)
            self.boxes.append(_mesh_box(mesh) if mesh is not None else _local_box(ob))
        else:
            k = None
        self.accepted[key] = k
        return k

    def owner(self, name: str) -> int:
        self.owners.append(name)
        return len(self.owners) - 1

    def object(self, ob) -> None:
        if ob.instance_type != "NONE" or len(getattr(ob, "particle_systems", ())):
            raise _NeedsWalk(f"{ob.name} makes instances the walk reads")
        world = np.array(ob.matrix_world, dtype=np.float64)
        if ob.type in GEOMETRY_TYPES and not shows_no_faces(ob):
            k = self.key_id(object_key(ob), ob)
            if k is not None:
                self.sources.append((world,))
                seen = _seen(ob, None, self.indirect, self.indirect_by)
                self.chunks.append((k, seen + (self.held(ob) or self.surface_held(ob),), self.owner(ob.name),
                                    len(self.sources) - 1,
                                    None, None, (0, ob.original.as_pointer()) if self.linked else None))
        if ob.type in INSTANCER_TYPES and _has_nodes(ob):
            self.instances_of(ob.evaluated_geometry(), ob, world)

    def leaves(self, ref, instancer) -> list:
        """What one instance reference draws: [(key id, local matrix or None, flags, owner)]; flags: (casts,
        seen by the camera, held out by its materials)."""
        import bpy
        if isinstance(ref, bpy.types.Object):
            ob = ref.evaluated_get(self.depsgraph) if not ref.is_evaluated else ref
            if ob.instance_type != "NONE" or (ob.type in INSTANCER_TYPES and _has_nodes(ob)
                                                and ob.evaluated_geometry().instances_pointcloud() is not None):
                raise _NeedsWalk(f"instanced object {ob.name} makes instances itself")
            if ob.type not in GEOMETRY_TYPES or shows_no_faces(ob):
                return []
            k = self.key_id(object_key(ob), ob)
            return [] if k is None else [(k, None, _flags(ob) + (self.surface_held(ob),), ob.name)]
        if not isinstance(ref, bpy.types.GeometrySet):
            raise _NeedsWalk(f"{instancer.name} instances a {type(ref).__name__}")
        out = []
        mesh = ref.mesh
        if mesh is not None and len(mesh.polygons):
            k = self.key_id(generated_key(instancer, mesh, self.generated), instancer, mesh)
            if k is not None:
                out.append((k, None, _flags(instancer) + (self.surface_held(instancer, mesh),),
                            f"{instancer.name}/{mesh.name}"))
        nested = ref.instances_pointcloud()
        if nested is not None and len(nested.points):
            flat, ref_index = _instance_arrays(nested)
            transforms = _row_major(flat)
            inner = [self.leaves(r, instancer) for r in ref.instance_references()]
            for t, r in zip(transforms, ref_index):
                for k, m, flags, name in inner[r]:
                    out.append((k, t if m is None else t @ m, flags, name))
        return out

    def instances_of(self, gs, instancer, world: np.ndarray) -> None:
        cloud = gs.instances_pointcloud()
        if cloud is None or len(cloud.points) == 0:
            return
        flat, ref_index = _instance_arrays(cloud)
        refs = gs.instance_references()
        self.sources.append((world, flat, ref_index))
        source = len(self.sources) - 1
        held = self.held(instancer)              # instances are held out with their instancer (holdout_test)
        casts, camera = _seen(instancer, None, self.indirect, self.indirect_by)   # seen as it lets them (_seen)
        linkers = (instancer.original.as_pointer(), 0) if self.linked else None   # and linked as it (linkers_of)
        for r, ref in enumerate(refs):
            for k, local, flags, name in self.leaves(ref, instancer):
                self.chunks.append((k, (flags[0] and casts, flags[1] and camera, held or flags[2]), self.owner(name),
                                    source, r if len(refs) > 1 else None, local, linkers))

    def same_as(self, previous: Optional["InstanceSet"]) -> bool:
        """Whether this read gives exactly ``previous`` (same keys, boxes, chunks and raw arrays)."""
        old = getattr(previous, "_source", None)
        if old is None:
            return False
        key_list, chunks, sources = old
        if key_list != self.key_list or len(chunks) != len(self.chunks) or len(sources) != len(self.sources) or \
                not np.array_equal(np.array(self.boxes, dtype=np.float64).reshape(-1, 2, 3), previous.key_boxes):
            return False                    # (a mesh edited in place keeps its key but not its box)
        for a, b in zip(chunks, self.chunks):
            if a[:2] != b[:2] or a[3:5] != b[3:5] or not _same_local(a[5], b[5]) or a[6] != b[6]:
                return False
        return all(len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
                   for a, b in zip(sources, self.sources))

    def result(self, previous: Optional["InstanceSet"] = None) -> InstanceSet:
        if previous is not None and self.same_as(previous):
            return previous
        if not self.chunks:
            return InstanceSet()
        ids, mats, flags, owners = [], [], [], []
        transforms: dict = {}
        for k, flag, owner, source, reference, local, _ in self.chunks:
            src = self.sources[source]
            world = src[0]
            if len(src) == 1:
                m = world[None]
            else:
                if source not in transforms:
                    transforms[source] = _row_major(src[1])
                m = transforms[source]
                if reference is not None:
                    m = m[src[2] == reference]
                if local is not None:
                    m = m @ local
                if not np.array_equal(world, np.eye(4)):
                    m = world @ m
            ids.append(len(m))
            mats.append(m)
            flags.append(flag)
            owners.append(owner)
        counts = ids
        key_ids = np.repeat(np.array([c[0] for c in self.chunks], dtype=np.int64), counts)
        flags = np.array(flags, dtype=bool).reshape(-1, 3)
        out = InstanceSet(key_list=self.key_list, key_ids=key_ids, matrices=np.concatenate(mats).reshape(-1, 4, 4),
                          key_boxes=np.array(self.boxes, dtype=np.float64).reshape(-1, 2, 3),
                          casts=np.repeat(flags[:, 0], counts), receives=np.repeat(flags[:, 1], counts),
                          holdouts=np.repeat(flags[:, 2], counts),
                          linkers=np.repeat(np.array([c[6] for c in self.chunks], dtype=np.int64).reshape(-1, 2),
                                            counts, axis=0) if self.linked else np.zeros((0, 2), dtype=np.int64),
                          owners=self.owners, owner_ids=np.repeat(np.array(owners, dtype=np.int64), counts))
        out._source = (self.key_list, self.chunks, self.sources)
        return out


def _same_local(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return np.array_equal(a, b)


def _row_major(flat: np.ndarray) -> np.ndarray:
    """(N, 4, 4) float64 matrices from Blender's column-major float32 instance transforms."""
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


def _instance_arrays(cloud) -> tuple[np.ndarray, np.ndarray]:
    """The instance transforms of an instances point cloud as read, (N * 16)
    float32 column-major, and its (N,) reference indices."""
    n = len(cloud.points)
    flat = np.empty(n * 16, dtype=np.float32)
    cloud.attributes["instance_transform"].data.foreach_get("value", flat)
    ref_index = np.zeros(n, dtype=np.int32)
    attr = cloud.attributes.get(".reference_index")
    if attr is not None:
        attr.data.foreach_get("value", ref_index)
    return flat, ref_index


def fast_reader_available() -> bool:
    """Whether this Blender has ``Object.evaluated_geometry`` (4.3+)."""
    import bpy
    return hasattr(bpy.types.Object, "evaluated_geometry")


def read_instances(depsgraph, on_geometry: Optional[Callable] = None,
                   previous: Optional[InstanceSet] = None) -> Optional[InstanceSet]:
    """The scene's instances read as arrays (Blender 4.3+), or None where only
    :func:`walk_instances` reads them right (see the module docstring).
    ``on_geometry(key, ob_eval, mesh)``: as for the walk; ``mesh`` is the
    geometry-nodes mesh to read for "GN" keys (None: read ``ob_eval``).
    ``previous``: an earlier read; returned as it is when nothing changed."""
    if not fast_reader_available():
        return None
    reader = _Reader(depsgraph, on_geometry)
    try:
        for ob in depsgraph.objects:
            reader.object(ob)
    except _NeedsWalk:
        return None
    return reader.result(previous)


def scene_instances(depsgraph, on_geometry: Optional[Callable] = None,
                    previous: Optional[InstanceSet] = None) -> InstanceSet:
    """:func:`read_instances`, or the walk where it cannot read the scene.
    ``on_geometry(key, ob_eval, mesh)`` as for :func:`read_instances`."""
    got = read_instances(depsgraph, on_geometry, previous)
    if got is not None:
        return got
    walk_cb = None if on_geometry is None else (lambda key, ob: on_geometry(key, ob, None))
    return walk_instances(depsgraph, walk_cb)
