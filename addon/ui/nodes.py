"""Geometry-node tooling, built by this code (the source of truth), idempotent
and versioned (``node_group["lixel_version"]``; an older group is rebuilt in
place, so the modifiers that use it keep working). A group also keeps a
fingerprint of what was built (``node_group["lixel_fingerprint"]``): an older
group that no longer matches it (someone edited it without renaming it, or an
older Lixel built it without one) is never rebuilt. It is left as it is, the
user's from then on (kept with a fake user), the new version is built under the
next free name, Lixel's own modifiers are pointed at that, and the operator says
so, naming both groups (:func:`_keep_edited`). The texel material is versioned and kept the same way
(:func:`ensure_texel_material`).

The light matrices travel in a *matrix carrier*: the mesh object "Lixel Light
Matrices" with one point per shadow map and the point attributes
``lixel_light_matrix`` (FLOAT4X4, world -> light clip) and ``lixel_map_size``
(FLOAT2, texels), and ``lixel_map_unbounded`` (1 where the map's clip volume reaches
through infinity, by ``warp.geometry.finite_clip_volume_corners``: the rule the
overlays and the operators use, decided once in float64). A modifier cannot take a Matrix input (shared notes §5), so
the node groups take the carrier *object* and sample the matrix from it; when
the carrier's matrices change, every group using it follows.

* **Lixel Texel Grid** puts the shadow-map texel grid on any mesh (and leaves
  the mesh as it is for a map index the carrier does not hold: a map the setup no
  longer has, whose matrix would sample as a default). Per point it
  stores ``lixel_light_xyw`` = (x, y, w) of ``M @ [p, 1]`` (clip coordinates,
  affine in p, so they interpolate exactly across a face), ``lixel_texel`` =
  the texel coordinate ((x/w)·½+½)·W, ((y/w)·½+½)·H with the homogeneous divide
  done explicitly (Project Point divides by |w|, so it is not used), and
  ``lixel_map_size``; per face corner ``lixel_texel_color``, the texel parity
  at the face centre (for Workbench's Attribute colour, which shows it when
  the mesh has no colour attribute of its own: it is made the active one). The
  material "Lixel Texel Grid" divides per pixel and draws the parity checker
  exactly in EEVEE and Cycles. Verified by rendering in all three engines
  (tests/blender/test_nodes.py).
* **Lixel Frustum From Matrix** builds the clip volume of a map as a mesh: the
  unit cube's corners through the inverse matrix, divided by w; nothing for a
  volume through infinity, nor for a map index the carrier does not hold (a map
  the setup no longer has: its matrix would sample as a default, zero or identity).
"""
import hashlib
import logging

import bpy
import numpy as np

from ..scene.owned import (DEBUG_KEY, MADE_KEY, NAME_KEY, find_made, is_lixel_made, made_as, mark_made,
                           named_as_a_copy)
from ..warp.geometry import finite_clip_volume_corners
from ..warp.types import WarpError

TEXEL_GROUP = "Lixel Texel Grid"
FRUSTUM_GROUP = "Lixel Frustum From Matrix"
TEXEL_MATERIAL = "Lixel Texel Grid"
CARRIER_NAME = "Lixel Light Matrices"
DEBUG_COLLECTION = "Lixel Debug"
MATRIX_ATTRIBUTE = "lixel_light_matrix"
SIZE_ATTRIBUTE = "lixel_map_size"
UNBOUNDED_ATTRIBUTE = "lixel_map_unbounded"
XYW_ATTRIBUTE = "lixel_light_xyw"
TEXEL_ATTRIBUTE = "lixel_texel"
PARITY_COLOR_ATTRIBUTE = "lixel_texel_color"
TEXEL_MODIFIER = "Lixel Texel Grid"
FRUSTUM_MODIFIER = "Lixel Frustum"
VERSION_KEY = "lixel_version"
FINGERPRINT_KEY = "lixel_fingerprint"
SCENE_KEY = "lixel_scene"
"""Custom property on a debug collection: the scene it is Lixel's for (a scene's Linked Copy holds it too)."""
TEXEL_GROUP_VERSION = 2     # 2: the mesh as it is for a map the carrier does not hold (1 coloured by a default matrix)
FRUSTUM_GROUP_VERSION = 4   # 4: nothing for a map the carrier does not hold (3 drew a 2-unit cube there)
MATERIAL_VERSION = 1

log = logging.getLogger(__name__)

NAMED = 5
"""Objects a message names one by one; it counts the rest (Blender cuts a report at about 1,000 characters, so the
names of 4,000 objects left out why and what to do)."""


def listed(items: list) -> str:
    """The first :data:`NAMED` of ``items`` (strings), and how many more."""
    return ", ".join(items[:NAMED]) + (f" and {len(items) - NAMED:,} more" if len(items) > NAMED else "")


# --- small node-building helpers ------------------------------------------------------------------------------

def _socket(sockets, name):
    for s in sockets:
        if s.name == name and getattr(s, "enabled", True):
            return s
    raise KeyError(f"no socket {name!r} in {[s.name for s in sockets]}")


class _Builder:
    def __init__(self, tree):
        self.tree = tree
        self.x = 0

    def node(self, kind, **props):
        n = self.tree.nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        n.location = (self.x, 0)
        self.x += 200
        return n

    def link(self, out, inp):
        self.tree.links.new(out, inp)

    def math(self, op, a, b=None, c=None):
        n = self.node("ShaderNodeMath", operation=op)
        for i, v in enumerate((a, b, c)):
            if v is None:
                continue
            if isinstance(v, (int, float)):
                n.inputs[i].default_value = v
            else:
                self.link(v, n.inputs[i])
        return n.outputs[0]

    def vmath(self, op, a, b):
        n = self.node("ShaderNodeVectorMath", operation=op)
        for i, v in enumerate((a, b)):
            if isinstance(v, (tuple, list)):
                n.inputs[i].default_value = v
            else:
                self.link(v, n.inputs[i])
        return n.outputs["Value" if op == "DOT_PRODUCT" else "Vector"]

    def combine_xyz(self, x, y, z):
        n = self.node("ShaderNodeCombineXYZ")
        for i, v in enumerate((x, y, z)):
            if isinstance(v, (int, float)):
                n.inputs[i].default_value = v
            else:
                self.link(v, n.inputs[i])
        return n.outputs[0]

    def separate_xyz(self, v):
        n = self.node("ShaderNodeSeparateXYZ")
        self.link(v, n.inputs[0])
        return n.outputs

    def store(self, geometry, name, data_type, domain, value):
        n = self.node("GeometryNodeStoreNamedAttribute", data_type=data_type, domain=domain)
        self.link(geometry, _socket(n.inputs, "Geometry"))
        _socket(n.inputs, "Name").default_value = name
        self.link(value, _socket(n.inputs, "Value"))
        return _socket(n.outputs, "Geometry")


_LAYOUT = frozenset({"name", "label", "location", "location_absolute", "width", "height", "select", "hide",
                     "show_options", "show_preview", "show_texture", "use_custom_color", "color", "color_tag",
                     "warning_propagation", "description"})
"""Node properties that change how a group looks in the editor, never what it computes: not in its fingerprint."""


def _value(v):
    """A socket's or property's value as plain data for a fingerprint: floats to 6 significant digits, a datablock
    by name."""
    if isinstance(v, float):
        return float(f"{v:.6g}")
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    if isinstance(v, bpy.types.ID):
        return v.name
    if isinstance(v, (set, frozenset)):     # an enum flag: a set's order changes from one process to the next
        return tuple(sorted(str(x) for x in v))
    try:
        return tuple(_value(x) for x in v)
    except TypeError:
        return repr(v)


def fingerprint(tree) -> str:
    """What node tree ``tree`` computes, hashed: its interface, each node's kind, settings, unlinked input values
    and mute, and its links; not the layout (:data:`_LAYOUT`). Equal for a group as Lixel built it, saved and
    loaded; different once a node, link, setting or value is changed."""
    items = [(i.item_type, getattr(i, "in_out", ""), i.name, getattr(i, "socket_type", ""),
              _value(getattr(i, "default_value", None))) for i in tree.interface.items_tree]
    nodes = []
    for n in sorted(tree.nodes, key=lambda n: n.name):
        props = [(p.identifier, _value(getattr(n, p.identifier))) for p in n.bl_rna.properties
                 if p.type in ("BOOLEAN", "INT", "FLOAT", "STRING", "ENUM") and not p.is_readonly
                 and p.identifier not in _LAYOUT and not p.identifier.startswith("bl_")]
        inputs = [(i.identifier, _value(getattr(i, "default_value", None))) for i in n.inputs if not i.is_linked]
        nodes.append((n.name, n.bl_idname, props, inputs))
    links = sorted((k.from_node.name, k.from_socket.identifier, k.to_node.name, k.to_socket.identifier, k.is_muted)
                   for k in tree.links)
    return hashlib.sha256(repr((items, nodes, links)).encode()).hexdigest()


def _reset_tree(name, tree_type, version):
    """Lixel's node tree ``name``: (None, tree, None) if it is current, else (tree, None, edited): ``tree``
    emptied for a rebuild, in place where Lixel's outdated group still holds what it built, else new (``edited``:
    that group, differing from its fingerprint, left to the user). A user's tree of that name is never touched."""
    tree = find_made(bpy.data.node_groups, name)
    if tree is not None and tree.bl_idname == tree_type and tree.get(VERSION_KEY) == version:
        return None, tree, None
    edited = None
    if tree is not None and tree.bl_idname == tree_type and tree.get(FINGERPRINT_KEY) != fingerprint(tree):
        edited, tree = tree, None
    if tree is None or tree.bl_idname != tree_type:
        tree = mark_made(bpy.data.node_groups.new(name, tree_type), name)
    tree.nodes.clear()
    tree.interface.clear()
    return tree, None, edited


def _built(tree, version: int, edited, notes):
    """Stamp the rebuilt ``tree`` with ``version`` and its fingerprint; where an ``edited`` group was left,
    :func:`_keep_edited`."""
    tree[VERSION_KEY] = version
    tree[FINGERPRINT_KEY] = fingerprint(tree)
    if edited is not None:
        _keep_edited(edited, tree, notes)
    return tree


def _keep_edited(edited, tree, notes) -> None:
    """Leave ``edited`` (an outdated group of Lixel's that is not what Lixel built) as it is, the user's from now on
    (Lixel's marks off, a fake user so it is saved though nothing may use it), point Lixel's own modifiers from it
    to its new version ``tree``, and say so in ``notes`` (a list of messages; None: the log)."""
    moved = []
    for ob in (ob for ob in bpy.data.objects if ob.library is None):    # a linked object's modifiers are its file's
        for mod in ob.modifiers:
            if mod.type == "NODES" and mod.node_group == edited and \
                    mod.name.split(".")[0] in (TEXEL_MODIFIER, FRUSTUM_MODIFIER):
                values = {}
                for name in ("Light Matrices", "Map Index", "Material"):
                    try:
                        values[name] = mod[_input(edited, name)]
                    except KeyError:    # an input the user took out of their group
                        pass
                mod.node_group = tree
                for name, value in values.items():
                    _set_input(mod, tree, name, value)
                moved.append(ob.name)
    _leave_to_user(edited, tree, "node group", moved, notes)


def _leave_to_user(edited, new, kind: str, moved: list, notes) -> None:
    """Take Lixel's marks off ``edited`` (a ``kind`` of Lixel's that is not what Lixel built), give it a fake user,
    and say in ``notes`` (None: the log) that Lixel's ``new`` version replaces it on the objects ``moved``."""
    old = edited.get(VERSION_KEY)
    for key in (MADE_KEY, NAME_KEY, VERSION_KEY, FINGERPRINT_KEY):
        if key in edited.keys():
            del edited[key]
    edited.use_fake_user = True
    said = (f"Lixel: {kind} '{edited.name}' (version {old}) is not as Lixel built it (edited, or made before Lixel "
            f"kept a fingerprint), so it was left as it is, yours now (with a fake user, so it is saved); Lixel's "
            f"version {new[VERSION_KEY]} is '{new.name}'"
            + (f", now used by Lixel's modifiers on {listed([repr(n) for n in moved])}" if moved else "")
            + f": to keep your edits, point those modifiers back to '{edited.name}' or copy them into '{new.name}'")
    if notes is None:
        log.warning("%s", said)
    else:
        notes.append(said)


def _carrier_matrix(b: _Builder, carrier_socket, index_socket, second=(SIZE_ATTRIBUTE, "FLOAT_VECTOR")):
    """(matrix, ``second`` attribute: the map size) sampled from the carrier object's point ``index``."""
    info = b.node("GeometryNodeObjectInfo", transform_space="ORIGINAL")
    b.link(carrier_socket, _socket(info.inputs, "Object"))
    values = []
    for attr, dtype in ((MATRIX_ATTRIBUTE, "FLOAT4X4"), second):
        named = b.node("GeometryNodeInputNamedAttribute", data_type=dtype)
        _socket(named.inputs, "Name").default_value = attr
        sample = b.node("GeometryNodeSampleIndex", data_type=dtype, domain="POINT")
        b.link(_socket(info.outputs, "Geometry"), _socket(sample.inputs, "Geometry"))
        b.link(_socket(named.outputs, "Attribute"), _socket(sample.inputs, "Value"))
        b.link(index_socket, _socket(sample.inputs, "Index"))
        values.append(_socket(sample.outputs, "Value"))
    return values


def _homogeneous_w(b: _Builder, matrix, point):
    """w = M[3] · [p, 1] (the 4th row of M, which Transform Point drops)."""
    sep = b.node("FunctionNodeSeparateMatrix")
    b.link(matrix, sep.inputs[0])
    row4 = b.combine_xyz(*(_socket(sep.outputs, f"Column {c} Row 4") for c in (1, 2, 3)))
    return b.math("ADD", b.vmath("DOT_PRODUCT", point, row4), _socket(sep.outputs, "Column 4 Row 4"))


def _transform_point(b: _Builder, matrix, point):
    n = b.node("FunctionNodeTransformPoint")
    b.link(point, _socket(n.inputs, "Vector"))
    b.link(matrix, _socket(n.inputs, "Transform"))
    return _socket(n.outputs, "Vector")


def _self_transform(b: _Builder):
    me = b.node("GeometryNodeSelfObject")
    info = b.node("GeometryNodeObjectInfo", transform_space="ORIGINAL")
    b.link(me.outputs[0], _socket(info.inputs, "Object"))
    return _socket(info.outputs, "Transform")


def _new_input(tree, name, socket_type, default=None, min_value=None):
    s = tree.interface.new_socket(name, in_out="INPUT", socket_type=socket_type)
    if default is not None:
        s.default_value = default
    if min_value is not None:
        s.min_value = min_value
    return s


# --- the groups -----------------------------------------------------------------------------------------------

def ensure_texel_grid_group(notes=None):
    """The "Lixel Texel Grid" geometry node group (built or rebuilt if outdated; ``notes``: see :func:`_keep_edited`).
    For a ``Map Index`` at or beyond the carrier's point count (a map the setup no longer has) it passes the mesh
    through as it is: Sample Index would give a default matrix, whose "texels" belong to no map."""
    tree, current, edited = _reset_tree(TEXEL_GROUP, "GeometryNodeTree", TEXEL_GROUP_VERSION)
    if tree is None:
        return current
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    _new_input(tree, "Light Matrices", "NodeSocketObject")
    _new_input(tree, "Map Index", "NodeSocketInt", 0, 0)
    _new_input(tree, "Material", "NodeSocketMaterial")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    b = _Builder(tree)
    gin = b.node("NodeGroupInput")
    gout = b.node("NodeGroupOutput")
    matrix, size = _carrier_matrix(b, _socket(gin.outputs, "Light Matrices"), _socket(gin.outputs, "Map Index"))
    world = _transform_point(b, _self_transform(b), b.node("GeometryNodeInputPosition").outputs[0])
    clip = b.separate_xyz(_transform_point(b, matrix, world))
    w = _homogeneous_w(b, matrix, world)
    size_xy = b.separate_xyz(size)
    # explicit homogeneous divide (Project Point would divide by |w|)
    u = b.math("MULTIPLY", b.math("MULTIPLY_ADD", b.math("DIVIDE", clip[0], w), 0.5, 0.5), size_xy[0])
    v = b.math("MULTIPLY", b.math("MULTIPLY_ADD", b.math("DIVIDE", clip[1], w), 0.5, 0.5), size_xy[1])
    texel = b.combine_xyz(u, v, 0.0)
    parity = b.math("FLOORED_MODULO", b.math("ADD", b.math("FLOOR", u), b.math("FLOOR", v)), 2.0)
    at_face = b.node("GeometryNodeFieldOnDomain", data_type="FLOAT", domain="FACE")
    b.link(parity, _socket(at_face.inputs, "Value"))
    parity_face = _socket(at_face.outputs, "Value")
    colour = b.node("ShaderNodeMix", data_type="RGBA")
    b.link(parity_face, _socket(colour.inputs, "Factor"))
    colour.inputs[6].default_value = (0.9, 0.9, 0.9, 1.0)   # A (RGBA)
    colour.inputs[7].default_value = (0.08, 0.08, 0.1, 1.0)  # B (RGBA)
    geo = _socket(gin.outputs, "Geometry")
    geo = b.store(geo, XYW_ATTRIBUTE, "FLOAT_VECTOR", "POINT", b.combine_xyz(clip[0], clip[1], w))
    geo = b.store(geo, TEXEL_ATTRIBUTE, "FLOAT_VECTOR", "POINT", texel)
    geo = b.store(geo, SIZE_ATTRIBUTE, "FLOAT_VECTOR", "POINT", size)
    geo = b.store(geo, PARITY_COLOR_ATTRIBUTE, "FLOAT_COLOR", "CORNER", colour.outputs[2])
    setmat = b.node("GeometryNodeSetMaterial")
    b.link(geo, _socket(setmat.inputs, "Geometry"))
    b.link(_socket(gin.outputs, "Material"), _socket(setmat.inputs, "Material"))
    switch = b.node("GeometryNodeSwitch", input_type="GEOMETRY")
    b.link(_map_missing(b, gin), _socket(switch.inputs, "Switch"))
    b.link(_socket(setmat.outputs, "Geometry"), _socket(switch.inputs, "False"))
    b.link(_socket(gin.outputs, "Geometry"), _socket(switch.inputs, "True"))
    b.link(_socket(switch.outputs, "Output"), gout.inputs[0])
    return _built(tree, TEXEL_GROUP_VERSION, edited, notes)


def _map_missing(b: _Builder, gin):
    """True where the group's ``Map Index`` is at or beyond the carrier's point count: a map it does not hold."""
    carrier = b.node("GeometryNodeObjectInfo", transform_space="ORIGINAL")
    b.link(_socket(gin.outputs, "Light Matrices"), _socket(carrier.inputs, "Object"))
    maps = b.node("GeometryNodeAttributeDomainSize", component="MESH")
    b.link(_socket(carrier.outputs, "Geometry"), _socket(maps.inputs, "Geometry"))
    missing = b.node("FunctionNodeCompare", data_type="INT", operation="GREATER_EQUAL")   # index >= the maps held
    b.link(_socket(gin.outputs, "Map Index"), _socket(missing.inputs, "A"))
    b.link(_socket(maps.outputs, "Point Count"), _socket(missing.inputs, "B"))
    return _socket(missing.outputs, "Result")


def ensure_frustum_group(notes=None):
    """The "Lixel Frustum From Matrix" group: the clip volume of map ``Map Index``
    of the carrier, in the modified object's local space; nothing where that volume
    reaches through infinity (the carrier's ``lixel_map_unbounded``: a corner at w
    <= 0, which the divide by w would mirror into a box the map does not cover, or
    at a w so small that the box is its far reach, not its shape; and, where float32
    evaluation puts a corner at w <= 0 all the same, nothing rather than a mirror); nothing for a ``Map Index`` at
    or beyond the carrier's point count (a map the setup no longer has: Sample Index would give the default matrix).
    ``notes``: see :func:`_keep_edited`."""
    tree, current, edited = _reset_tree(FRUSTUM_GROUP, "GeometryNodeTree", FRUSTUM_GROUP_VERSION)
    if tree is None:
        return current
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")  # unused; must be first
    _new_input(tree, "Light Matrices", "NodeSocketObject")
    _new_input(tree, "Map Index", "NodeSocketInt", 0, 0)
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    b = _Builder(tree)
    gin = b.node("NodeGroupInput")
    gout = b.node("NodeGroupOutput")
    matrix, unbounded = _carrier_matrix(b, _socket(gin.outputs, "Light Matrices"), _socket(gin.outputs, "Map Index"),
                                        (UNBOUNDED_ATTRIBUTE, "FLOAT"))
    inv = b.node("FunctionNodeInvertMatrix")
    b.link(matrix, _socket(inv.inputs, "Matrix"))
    inverse = _socket(inv.outputs, "Matrix")
    cube = b.node("GeometryNodeMeshCube")
    _socket(cube.inputs, "Size").default_value = (2.0, 2.0, 2.0)
    for axis in "XYZ":
        _socket(cube.inputs, f"Vertices {axis}").default_value = 2
    ndc = b.node("GeometryNodeInputPosition").outputs[0]
    xyz = _transform_point(b, inverse, ndc)
    w = _homogeneous_w(b, inverse, ndc)
    world = b.vmath("DIVIDE", xyz, b.combine_xyz(w, w, w))
    inv_self = b.node("FunctionNodeInvertMatrix")
    b.link(_self_transform(b), _socket(inv_self.inputs, "Matrix"))
    local = _transform_point(b, _socket(inv_self.outputs, "Matrix"), world)
    setpos = b.node("GeometryNodeSetPosition")
    b.link(_socket(cube.outputs, "Mesh"), _socket(setpos.inputs, "Geometry"))
    b.link(local, _socket(setpos.inputs, "Position"))
    stat = b.node("GeometryNodeAttributeStatistic", data_type="FLOAT", domain="POINT")
    b.link(_socket(cube.outputs, "Mesh"), _socket(stat.inputs, "Geometry"))
    b.link(w, _socket(stat.inputs, "Attribute"))
    behind = b.node("FunctionNodeCompare", data_type="FLOAT", operation="LESS_EQUAL")
    b.link(_socket(stat.outputs, "Min"), _socket(behind.inputs, "A"))
    _socket(behind.inputs, "B").default_value = 0.0
    either = b.node("FunctionNodeBooleanMath", operation="OR")
    b.link(_socket(behind.outputs, "Result"), either.inputs[0])
    b.link(unbounded, either.inputs[1])  # 0 or 1; Blender converts a float to a boolean as > 0
    missing = _map_missing(b, gin)
    empty = b.node("FunctionNodeBooleanMath", operation="OR")
    b.link(_socket(either.outputs, "Boolean"), empty.inputs[0])
    b.link(missing, empty.inputs[1])
    delete = b.node("GeometryNodeDeleteGeometry", domain="POINT")
    b.link(_socket(setpos.outputs, "Geometry"), _socket(delete.inputs, "Geometry"))
    b.link(_socket(empty.outputs, "Boolean"), _socket(delete.inputs, "Selection"))
    b.link(_socket(delete.outputs, "Geometry"), gout.inputs[0])
    return _built(tree, FRUSTUM_GROUP_VERSION, edited, notes)


def ensure_texel_material(notes=None):
    """The "Lixel Texel Grid" material: per-pixel texel parity from the
    interpolated clip coordinates (x, y, w) with the divide done per pixel, so
    texel edges are exact in EEVEE and Cycles. Workbench shows the per-face
    ``lixel_texel_color`` (Viewport Shading > Color > Attribute; ``color_type`` 'VERTEX' in the API).
    Versioned and fingerprinted as the groups are: an outdated material whose nodes differ from what Lixel built is
    left to the user, and the new version is built beside it (:func:`_keep_edited_material`)."""
    mat = find_made(bpy.data.materials, TEXEL_MATERIAL)
    if mat is not None and mat.get(VERSION_KEY) == MATERIAL_VERSION:
        return mat
    edited = None
    if mat is not None and (mat.node_tree is None or mat.get(FINGERPRINT_KEY) != fingerprint(mat.node_tree)):
        edited, mat = mat, None
    if mat is None:
        mat = mark_made(bpy.data.materials.new(TEXEL_MATERIAL), TEXEL_MATERIAL)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    b = _Builder(tree)
    xyw = b.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=XYW_ATTRIBUTE)
    size = b.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=SIZE_ATTRIBUTE)
    c = b.separate_xyz(_socket(xyw.outputs, "Vector"))
    s = b.separate_xyz(_socket(size.outputs, "Vector"))
    u = b.math("FLOOR", b.math("MULTIPLY", b.math("MULTIPLY_ADD", b.math("DIVIDE", c[0], c[2]), 0.5, 0.5), s[0]))
    v = b.math("FLOOR", b.math("MULTIPLY", b.math("MULTIPLY_ADD", b.math("DIVIDE", c[1], c[2]), 0.5, 0.5), s[1]))
    parity = b.math("FLOORED_MODULO", b.math("ADD", u, v), 2.0)
    mix = b.node("ShaderNodeMix", data_type="RGBA")
    b.link(parity, _socket(mix.inputs, "Factor"))
    mix.inputs[6].default_value = (0.9, 0.9, 0.9, 1.0)
    mix.inputs[7].default_value = (0.08, 0.08, 0.1, 1.0)
    bsdf = b.node("ShaderNodeBsdfDiffuse")
    b.link(mix.outputs[2], _socket(bsdf.inputs, "Color"))
    out = b.node("ShaderNodeOutputMaterial")
    b.link(bsdf.outputs[0], _socket(out.inputs, "Surface"))
    mat.diffuse_color = (0.6, 0.6, 0.6, 1.0)
    mat[VERSION_KEY] = MATERIAL_VERSION
    mat[FINGERPRINT_KEY] = fingerprint(tree)
    if edited is not None:
        _keep_edited_material(edited, mat, notes)
    return mat


def _keep_edited_material(edited, mat, notes) -> None:
    """:func:`_keep_edited` for the texel material: Lixel's texel-grid modifiers that set ``edited`` (and the slot an
    earlier :func:`add_texel_grid` added for it on their meshes) take its new version ``mat``."""
    moved = []
    for ob in (ob for ob in bpy.data.objects if ob.library is None):
        mod = lixel_modifier(ob, TEXEL_MODIFIER)
        try:
            key = None if mod is None else _input(mod.node_group, "Material")
        except KeyError:    # an input the user took out of Lixel's group
            continue
        if key is None or mod.get(key) != edited:
            continue
        mod[key] = mat
        slots = ob.data.materials
        if ob.data.library is None and (index := slots.find(edited.name)) >= 0:
            slots[index] = mat
        moved.append(ob.name)
    _leave_to_user(edited, mat, "material", moved, notes)


# --- the matrix carrier and the objects using the groups --------------------------------------------------------

def debug_collection(scene):
    """``scene``'s "Lixel Debug" collection: the one Lixel made that the scene holds, else one Lixel made that no
    scene holds, else a new one, linked to the scene. Each scene has its own (a second scene's is "Lixel
    Debug.001"), so baking or syncing in one never rewrites what another shows. A user's collection of that name
    is left alone. The scene's settings point at it (``scene.lixel.debug_collection``): Scene > New > Full Copy
    copies the collection and the objects in it under copies' names and points the new scene at the copy, which
    is then Lixel's (:func:`_adopt_scene_copy`). Before, the copy was taken for the user's, so Sync wrote a second
    carrier that the copied texel grids and frusta did not follow, and Bake a second set beside the stale one.
    Scene > New > Linked Copy links the same collection into the new scene (and points its settings at it): it
    stays the scene's it was made for (``SCENE_KEY``), and the other scene, on its first Sync or Bake, leaves it
    and takes its own. Before, Sync or Bake in a linked copy rewrote the carrier and the baked objects of the first
    scene, so its texel grids and B showed the copy's method and camera without a word."""
    coll = scene.lixel.debug_collection
    if coll is None or coll.library is not None or scene.collection.children.get(coll.name) != coll or \
            not (made_as(coll, DEBUG_COLLECTION) or _adopt_scene_copy(coll)):
        coll = next((c for c in scene.collection.children if c.library is None and made_as(c, DEBUG_COLLECTION)),
                    None)
    owner = None if coll is None else coll.get(SCENE_KEY)
    if isinstance(owner, bpy.types.Scene) and owner != scene and owner.collection.children.get(coll.name) == coll:
        scene.collection.children.unlink(coll)  # its scene keeps it; this one takes its own
        coll = None
    if coll is None:
        held = {c.name for s in bpy.data.scenes for c in s.collection.children}
        coll = next((c for c in bpy.data.collections if c.library is None and c.name not in held
                     and made_as(c, DEBUG_COLLECTION)), None)
        if coll is None:
            coll = mark_made(bpy.data.collections.new(DEBUG_COLLECTION), DEBUG_COLLECTION)
        scene.collection.children.link(coll)
    if scene.lixel.debug_collection != coll:
        scene.lixel.debug_collection = coll
    if coll.get(SCENE_KEY) != scene:
        coll[SCENE_KEY] = scene
    return coll


def _adopt_scene_copy(coll) -> bool:
    """Make ``coll``, the copy of a debug collection that a scene's settings point at, Lixel's again with the debug
    objects in it (and meshes only they show) that are copies of Lixel's (``owned.named_as_a_copy``). Where two
    objects are copies of one made name (the user's Shift+D copy went along) neither is taken: one may be the
    user's. Whether ``coll`` is such a copy."""
    if coll.get(MADE_KEY) != DEBUG_COLLECTION or not named_as_a_copy(coll):
        return False
    mark_made(coll, DEBUG_COLLECTION)
    copies = [ob for ob in coll.objects if DEBUG_KEY in ob.keys() and named_as_a_copy(ob)]
    made = [ob[MADE_KEY] for ob in copies]
    for ob in (ob for ob in copies if made.count(ob[MADE_KEY]) == 1):
        mark_made(ob, ob[MADE_KEY])
        if ob.data is not None and ob.data.users == 1 and named_as_a_copy(ob.data):
            mark_made(ob.data, ob.data[MADE_KEY])
    return True


def scene_debug_object(scene, name: str):
    """The object Lixel made as ``name`` in ``scene``'s debug collection, or None."""
    return next((ob for ob in debug_collection(scene).objects if made_as(ob, name)), None)


def lixel_mesh(name, scene):
    """The mesh for ``scene``'s Lixel object ``name``: the one it shows when Lixel made it and nothing else shows
    it (a copy the user keeps may share it), else a new one. Never a user's mesh, whatever its name."""
    mesh = getattr(scene_debug_object(scene, name), "data", None)
    if mesh is not None and mesh.users == 1 and is_lixel_made(mesh):
        return mesh
    return mark_made(bpy.data.meshes.new(name), name)


def debug_object(scene, name, kind, data):
    """``scene``'s debug object ``name`` in its debug collection, given ``data`` (reused
    if Lixel made it before: re-baking replaces the data, never duplicates the
    object). A user's object of that name, or another scene's, is left alone: this one takes the next
    free name."""
    coll = debug_collection(scene)
    ob = scene_debug_object(scene, name)
    if ob is None:
        ob = mark_made(bpy.data.objects.new(name, data), name)
    elif ob.data is not data:
        old = ob.data
        ob.data = data
        if old is not None and old.users == 0 and is_lixel_made(old):
            bpy.data.meshes.remove(old)
    ob[DEBUG_KEY] = kind
    if ob.name not in coll.objects:
        coll.objects.link(ob)
    return ob


def write_matrices(mesh, matrices, sizes) -> None:
    """Put (N, 4, 4) row-major matrices, (N, 2) sizes and whether each clip volume reaches through infinity on the
    carrier mesh's N points."""
    mats = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
    n = len(mats)
    if len(mesh.vertices) != n:
        mesh.clear_geometry()
        mesh.vertices.add(n)
    for name, dtype in ((MATRIX_ATTRIBUTE, "FLOAT4X4"), (SIZE_ATTRIBUTE, "FLOAT_VECTOR"), (UNBOUNDED_ATTRIBUTE, "FLOAT")):
        attr = mesh.attributes.get(name)
        if attr is None or attr.data_type != dtype or attr.domain != "POINT":
            if attr is not None:
                mesh.attributes.remove(attr)
            mesh.attributes.new(name, dtype, "POINT")
    # FLOAT4X4 attribute values are column-major (shared notes §3/§5)
    mesh.attributes[MATRIX_ATTRIBUTE].data.foreach_set("value", mats.transpose(0, 2, 1).astype(np.float32).ravel())
    sz = np.zeros((n, 3), dtype=np.float32)
    sz[:, :2] = np.asarray(sizes, dtype=np.float32).reshape(-1, 2)
    mesh.attributes[SIZE_ATTRIBUTE].data.foreach_set("vector", sz.ravel())
    unbounded = [float(finite_clip_volume_corners(m) is None) for m in mats]
    mesh.attributes[UNBOUNDED_ATTRIBUTE].data.foreach_set("value", np.array(unbounded, dtype=np.float32))
    mesh.update()


def ensure_carrier(scene, setup):
    """The matrix carrier object holding ``setup``'s maps (updated in place)."""
    mesh = lixel_mesh(CARRIER_NAME, scene)
    write_matrices(mesh, [m.matrix for m in setup.maps], [m.size for m in setup.maps])
    ob = debug_object(scene, CARRIER_NAME, "carrier", mesh)
    ob.hide_render = True
    ob.matrix_world = ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))
    ob.update_tag(refresh={"DATA"})
    return ob


def _input(tree, name: str) -> str:
    """The identifier of ``tree``'s input ``name`` (a modifier's key for its value)."""
    for item in tree.interface.items_tree:
        if getattr(item, "in_out", None) == "INPUT" and item.name == name:
            return item.identifier
    raise KeyError(name)


def _lixel_input(tree, name: str) -> str:
    """:func:`_input`, or WarpError naming the group where it has no such input (someone edited Lixel's group
    without renaming it: it is still Lixel's, but not as Lixel built it)."""
    try:
        return _input(tree, name)
    except KeyError:
        raise WarpError(f"node group '{tree.name}' has no input '{name}' (was it edited?): rename it to keep it as "
                        f"yours, and Lixel builds its own again") from None


def _set_input(mod, tree, name, value):
    mod[_lixel_input(tree, name)] = value


def _matrix_modifier(ob, name: str, group, carrier, map_index: int, *more: str):
    """The object's geometry-nodes modifier ``name`` (made if missing) running
    ``group`` on the light matrices of ``carrier``, map ``map_index``. WarpError, before anything changes, where
    ``group`` lacks one of its inputs or ``more``."""
    for needed in ("Light Matrices", "Map Index", *more):
        _lixel_input(group, needed)
    mod = lixel_modifier(ob, name)
    if mod is None:  # a user's modifier of that name keeps it: Blender names this one "<name>.001"
        mod = ob.modifiers.new(name, "NODES")
    mod.node_group = group
    _set_input(mod, group, "Light Matrices", carrier)
    _set_input(mod, group, "Map Index", int(map_index))
    return mod


def reattach_orphans(scene, carrier) -> list:
    """Point the Lixel frustum and texel-grid modifiers of ``scene``'s objects that follow no carrier (the carrier
    object was deleted: Blender cleared their Light Matrices, so they showed nothing while Sync said the matrices
    were synced) at ``carrier``, this scene's; the names of their objects."""
    out = []
    for ob in (ob for ob in scene.objects if ob.library is None):
        for name in (FRUSTUM_MODIFIER, TEXEL_MODIFIER):
            mod = lixel_modifier(ob, name)
            try:
                key = None if mod is None else _input(mod.node_group, "Light Matrices")
            except KeyError:    # a group of Lixel's that someone took the input out of
                continue
            if key is not None and mod.get(key) is None:
                mod[key] = carrier
                ob.update_tag()
                out.append(ob.name)
    return out


def followers_of_other_carriers(objects, carrier, scene) -> dict:
    """{object name: (carrier name, its scene's name or "")} for each of ``objects`` whose Lixel frustum or
    texel-grid modifier follows a carrier other than ``carrier``, ``scene``'s, which Sync does not write: another
    scene's (an object in several scenes, a Linked Copy's, shows one scene's matrices) or one the user renamed or
    copied (the user's from then on; "" for the scene: this scene holds it)."""
    out = {}
    for ob in (ob for ob in objects if ob.library is None):
        for name in (FRUSTUM_MODIFIER, TEXEL_MODIFIER):
            mod = lixel_modifier(ob, name)
            try:
                other = None if mod is None else mod[_input(mod.node_group, "Light Matrices")]
            except KeyError:    # a group of Lixel's that someone took the input out of
                continue
            if other is not None and other != carrier:
                scenes = [s.name for s in other.users_scene]
                out[ob.name] = other.name, scenes[0] if scenes and scene.name not in scenes else ""
    return out


def followers_of_missing_maps(carrier, count: int) -> list:
    """(object name, map index) of every object whose Lixel frustum or texel-grid modifier follows ``carrier``'s map
    ``index`` >= ``count``, a map the carrier no longer holds (the setup has fewer maps since it was added): the
    groups would read a default matrix there: a frustum shows nothing (a group before version 4 of
    :data:`FRUSTUM_GROUP_VERSION`: a 2-unit cube at the origin), a texel grid leaves the mesh as it is (before
    version 2 of :data:`TEXEL_GROUP_VERSION`: the colours of no map's texels)."""
    out = []
    for ob in bpy.data.objects:
        for name in (FRUSTUM_MODIFIER, TEXEL_MODIFIER):
            mod = lixel_modifier(ob, name)
            try:
                follows = mod is not None and mod[_input(mod.node_group, "Light Matrices")] == carrier
                index = int(mod[_input(mod.node_group, "Map Index")]) if follows else -1
            except KeyError:    # a group of Lixel's that someone took an input out of follows no map of Lixel's
                continue
            if index >= count:
                out.append((ob.name, index))
    return out


def lixel_modifier(ob, name: str):
    """The geometry-nodes modifier Lixel added to ``ob`` as ``name`` (it runs one of Lixel's node groups, or an
    unedited copy of one: :func:`is_appended_group`), or None."""
    for mod in ob.modifiers:
        if mod.type == "NODES" and mod.name.split(".")[0] == name and \
                (is_lixel_made(mod.node_group) or is_appended_group(mod.node_group)):
            return mod
    return None


def is_appended_group(tree) -> bool:
    """Whether ``tree`` is Lixel's texel-grid or frustum group under a copy's name and as Lixel built it (its
    fingerprint): what appending an object with a grid from another .blend brings along where this file has the
    group already ("Lixel Texel Grid.001"). Its modifiers were taken for a user's: Remove Texel Grid said it
    removed nothing, and Add Texel Grid stacked a second grid on the object. A copy the user edited is theirs."""
    return tree is not None and tree.library is None and tree.get(MADE_KEY) in (TEXEL_GROUP, FRUSTUM_GROUP) and \
        named_as_a_copy(tree) and tree.get(FINGERPRINT_KEY) == fingerprint(tree)


def is_files_own(mesh) -> bool:
    """Whether what Lixel writes on ``mesh`` stays with the file: a mesh linked from a library is its library's, and a
    library override keeps only the changes of properties Blender lets it override (its colour attribute names come
    back empty on reload). A library override *object* keeps a modifier added to it."""
    return mesh.library is None and mesh.override_library is None


def add_texel_grid(ob, carrier, map_index: int = 0, notes=None):
    """Add (or update) the texel-grid modifier on mesh object ``ob`` (``notes``: see :func:`_keep_edited`). The group
    sets the material itself (Set Material; the modifier's input keeps it saved): no slot is added to the mesh, whose
    other objects would show Lixel's material through it (a mesh without material: its faces use the first slot).
    A mesh that is not the file's own (:func:`is_files_own`: a library override's) is left as it is."""
    group = ensure_texel_grid_group(notes)
    mat = ensure_texel_material(notes)
    mod = _matrix_modifier(ob, TEXEL_MODIFIER, group, carrier, map_index, "Material")
    _set_input(mod, group, "Material", mat)
    attrs = ob.data.attributes
    if is_files_own(ob.data) and not attrs.active_color_name and not attrs.default_color_name:
        # Workbench's Attribute colour shows the active colour attribute; the mesh has none of its own,
        # so point it at the one the modifier makes (the name is all that is stored).
        attrs.active_color_name = attrs.default_color_name = PARITY_COLOR_ATTRIBUTE
    ob.update_tag()
    return mod


def remove_texel_grid(ob) -> bool:
    """:func:`remove_texel_grids` of ``ob`` alone: whether it had one."""
    return remove_texel_grids([ob]) == 1


def remove_texel_grids(objects) -> int:
    """Remove the texel-grid modifier from each of ``objects``; the colour attribute names it put on a mesh of the
    file's own (and the material slot an older Lixel added) go only with the last object of that mesh that has the grid
    (another still shows it through them). The objects left with a grid are found once, so removing the grids of
    a scene's many objects takes time in proportion to them (asked per object, it grew with their square: 10k tiles,
    a minute). Returns how many objects had one."""
    removed = []
    for ob in objects:
        mod = lixel_modifier(ob, TEXEL_MODIFIER)
        if mod is not None:
            ob.modifiers.remove(mod)
            removed.append(ob)
    if not removed:
        return 0
    gridded = {ob.data.name_full for ob in bpy.data.objects
               if ob.type == "MESH" and lixel_modifier(ob, TEXEL_MODIFIER) is not None}
    mat = find_made(bpy.data.materials, TEXEL_MATERIAL)
    for mesh in {ob.data.name_full: ob.data for ob in removed if ob.data.name_full not in gridded
                 and is_files_own(ob.data)}.values():
        attrs = mesh.attributes
        if attrs.active_color_name == PARITY_COLOR_ATTRIBUTE:
            attrs.active_color_name = ""
        if attrs.default_color_name == PARITY_COLOR_ATTRIBUTE:
            attrs.default_color_name = ""
        if mat is not None and (index := mesh.materials.find(mat.name)) >= 0:
            mesh.materials.pop(index=index)
    return len(removed)


def add_frustum_object(scene, carrier, map_index: int = 0, notes=None):
    """A debug object whose mesh is map ``map_index``'s clip volume, following the carrier (``notes``: see
    :func:`_keep_edited`)."""
    group = ensure_frustum_group(notes)
    name = f"Lixel Frustum (map {map_index})"
    ob = debug_object(scene, name, "frustum_nodes", lixel_mesh(name, scene))
    mod = _matrix_modifier(ob, FRUSTUM_MODIFIER, group, carrier, map_index)
    ob.display_type = "WIRE"
    ob.update_tag()
    return ob
