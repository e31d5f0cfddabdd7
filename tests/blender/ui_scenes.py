"""Tiny scenes for the UI, operator, node and script tests, built with bpy.data
(no operators, so building never depends on what is being tested)."""
import contextlib
import hashlib
import math

import bpy
import mathutils
import numpy as np


def _link(scene, name, data, location=(0, 0, 0), rotation=(0, 0, 0)):
    ob = bpy.data.objects.new(name, data)
    ob.location = location
    ob.rotation_euler = rotation
    scene.collection.objects.link(ob)
    return ob


def grid_mesh(name, size=10.0, cuts=4):
    """A flat grid of (cuts+1)^2 vertices in the XY plane, centred on the origin."""
    n = cuts + 1
    verts = [(size * (i / cuts - 0.5), size * (j / cuts - 0.5), 0.0) for j in range(n) for i in range(n)]
    faces = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(cuts) for i in range(cuts)]
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    return me


def cube_mesh(name, half=0.5):
    h = half
    verts = [(x, y, z) for z in (-h, h) for y in (-h, h) for x in (-h, h)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    return me


def look_at(ob, target):
    d = mathutils.Vector(target) - ob.location
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def build(scene, camera=True, light="SUN", mesh=True):
    """Fill ``scene``: a ground grid and a cube (``mesh``), a camera looking at
    them (``camera``), a light of type ``light`` (None: no light)."""
    if mesh:
        _link(scene, f"{scene.name} ground", grid_mesh(f"{scene.name} ground"))
        _link(scene, f"{scene.name} cube", cube_mesh(f"{scene.name} cube"), location=(0.5, 0.3, 0.5))
    if camera:
        cam = _link(scene, f"{scene.name} camera", bpy.data.cameras.new(f"{scene.name} camera"), location=(7, -6, 4))
        cam.data.clip_start, cam.data.clip_end = 0.1, 60.0
        look_at(cam, (0, 0, 0))
        scene.camera = cam
    if light:
        data = bpy.data.lights.new(f"{scene.name} {light.lower()}", light)
        if light == "SPOT":
            data.spot_size = math.radians(70)
        lob = _link(scene, f"{scene.name} light", data, location=(3, 2, 8))
        look_at(lob, (0, 0, 0))
    scene.render.resolution_x, scene.render.resolution_y = 640, 360
    return scene


def remove_scene(scene):
    """Delete a test scene, its objects and the data only they used."""
    for ob in list(scene.objects):
        data = ob.data
        bpy.data.objects.remove(ob)
        if data is not None and data.users == 0:
            for coll in (bpy.data.meshes, bpy.data.cameras, bpy.data.lights):
                if data.name in coll and coll[data.name] == data:
                    coll.remove(data)
                    break
    bpy.data.scenes.remove(scene)


@contextlib.contextmanager
def active_scene(name="lixel_ui", **kw):
    """A new scene built by :func:`build`, made the window's scene for the block."""
    window = bpy.context.window
    old = window.scene
    scene = bpy.data.scenes.new(name)
    window.scene = scene
    try:
        build(scene, **kw)
        bpy.context.view_layer.update()
        yield scene
    finally:
        window.scene = old
        remove_scene(scene)


def digest(idb) -> str:
    """A fingerprint of everything a user would notice changed in a datablock."""
    h = hashlib.sha256()
    h.update(repr((type(idb).__name__, idb.name, sorted(idb.keys()))).encode())
    if isinstance(idb, bpy.types.Mesh):
        co = np.empty(len(idb.vertices) * 3)
        idb.vertices.foreach_get("co", co)
        h.update(co.tobytes())
        h.update(repr((len(idb.polygons), len(idb.edges), [m.name if m else None for m in idb.materials],
                       sorted(a.name for a in idb.attributes))).encode())
    elif isinstance(idb, bpy.types.Object):
        h.update(repr((idb.data.name if idb.data else None, [tuple(r) for r in idb.matrix_world],
                       [(m.name, m.type) for m in idb.modifiers], idb.hide_render,
                       sorted(c.name for c in idb.users_collection))).encode())
    elif isinstance(idb, bpy.types.Collection):
        h.update(repr(sorted(o.name for o in idb.objects)).encode())
    elif isinstance(idb, bpy.types.NodeTree):
        h.update(repr((sorted(n.name for n in idb.nodes), len(idb.links),
                       [i.name for i in idb.interface.items_tree])).encode())
    elif isinstance(idb, bpy.types.Material):
        h.update(repr((tuple(idb.diffuse_color),
                       sorted(n.name for n in idb.node_tree.nodes) if idb.node_tree else None)).encode())
    elif isinstance(idb, bpy.types.Text):
        h.update(idb.as_string().encode())
    elif isinstance(idb, bpy.types.Image):
        px = np.empty(idb.size[0] * idb.size[1] * 4, dtype=np.float32)
        idb.pixels.foreach_get(px)
        h.update(repr(tuple(idb.size)).encode() + px.tobytes())
    return h.hexdigest()
