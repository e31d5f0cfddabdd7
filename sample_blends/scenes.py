"""The sample scenes, built from nothing by code (this file is their source of truth).

Every builder starts from an empty file, makes one light, one camera with an
animation over ``FRAMES`` frames (for the flicker measurement) and white diffuse
materials, and returns the scene. ``sample_blends/build.py`` saves them as .blend.

| name       | what                                                   | after                          |
|------------|--------------------------------------------------------|--------------------------------|
| forest     | 10,000 GN-instanced trees on a ground plane, sun       | Scherzer §5: fov 60°, 0.1–70   |
| chess      | a chessboard with pieces under a spot light            | PSM (Stamminger) Fig. 1        |
| floor_wall | a floor and a wall with objects on both, sun           | Lixel (Chong-Gortler) §4       |
| terrain    | hilly terrain with a town of instanced buildings, sun  | GMNPR §4: fov 60°, near 1, 800 |
| telephoto  | a street seen through a 200 mm lens, sun               | narrow FOV                     |
| tiny       | a plane, a cube and a sun (tests; not saved)           |                                |

Geometry is generated with numpy (deterministic seeds), never with operators,
so the builders run the same under Blender 4.2 and 5.0.
"""
from __future__ import annotations

import math

import bpy
import numpy as np

FRAMES = 8
"""Frames of camera animation (1..FRAMES)."""


# ---------------------------------------------------------------- helpers

def reset() -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, FRAMES
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.render.resolution_percentage = 100
    world = bpy.data.worlds.new("Black")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    return scene


def diffuse_material(name: str, albedo: float = 1.0) -> bpy.types.Material:
    """A fully rough diffuse material of grey ``albedo``, made once per ``name`` (its colour set on every call)."""
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        nt = mat.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Roughness"].default_value = 0.0
        nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_DIFFUSE")
    bsdf.inputs["Color"].default_value = mat.diffuse_color = (albedo, albedo, albedo, 1.0)
    return mat


def white_material() -> bpy.types.Material:
    """White, fully rough diffuse: the material every peer renders the shadow term with."""
    return diffuse_material("White diffuse")


def mesh_object(name: str, verts, faces, collection=None) -> bpy.types.Object:
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(verts, dtype=np.float64).tolist(), [], [list(map(int, f)) for f in faces])
    me.validate()
    me.update()
    me.materials.append(white_material())
    ob = bpy.data.objects.new(name, me)
    (collection or bpy.context.scene.collection).objects.link(ob)
    return ob


def merge(parts):
    """Concatenate (verts, faces) parts into one."""
    verts, faces, off = [], [], 0
    for v, f in parts:
        verts.append(np.asarray(v, dtype=np.float64))
        faces.extend([[i + off for i in face] for face in f])
        off += len(v)
    return np.concatenate(verts), faces


def box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)])
    f = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return v, f


def lathe(profile, segments=16, centre=(0, 0, 0)):
    """Surface of revolution about Z of a (r, z) profile. A row with r = 0 is a
    single vertex (a pole); open ends (r > 0) are closed with a fan."""
    prof = np.asarray(profile, dtype=np.float64)
    a = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    cx, cy, cz = centre
    v, rows = [], []
    for r, z in prof:
        if r <= 0:
            rows.append([len(v)])
            v.append([cx, cy, cz + z])
        else:
            rows.append(list(range(len(v), len(v) + segments)))
            v.extend([cx + r * math.cos(t), cy + r * math.sin(t), cz + z] for t in a)
    f = []
    for lo, hi in zip(rows[:-1], rows[1:]):
        for j in range(segments):
            j2 = (j + 1) % segments
            if len(lo) == 1 and len(hi) == 1:
                continue
            if len(lo) == 1:
                f.append((lo[0], hi[j2], hi[j]))
            elif len(hi) == 1:
                f.append((lo[j], lo[j2], hi[0]))
            else:
                f.append((lo[j], lo[j2], hi[j2], hi[j]))
    for row, z, up in ((rows[0], prof[0, 1], False), (rows[-1], prof[-1, 1], True)):
        if len(row) > 1:
            c = len(v)
            v.append([cx, cy, cz + z])
            for j in range(segments):
                j2 = (j + 1) % segments
                f.append((c, row[j], row[j2]) if up else (c, row[j2], row[j]))
    return np.array(v), f


def sphere(radius, centre, rings=10, segments=16):
    prof = [(radius * math.sin(t), -radius * math.cos(t)) for t in np.linspace(0.02, math.pi - 0.02, rings)]
    return lathe(prof, segments, centre)


def grid(xs, ys, height=None):
    """A grid surface over xs × ys with z = height(X, Y) (or 0)."""
    X, Y = np.meshgrid(xs, ys)
    Z = np.zeros_like(X) if height is None else height(X, Y)
    v = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    nx = len(xs)
    f = [(j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i)
         for j in range(len(ys) - 1) for i in range(nx - 1)]
    return v, f


def add_camera(scene, keys, lens=None, fov_deg=None, near=0.1, far=100.0, sensor=36.0):
    """A camera with one (location, look-at) key per entry of ``keys`` spread over the frames."""
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "HORIZONTAL"
    cam.sensor_width = sensor
    if lens is not None:
        cam.lens = lens
    if fov_deg is not None:
        cam.angle = math.radians(fov_deg)   # horizontal (sensor fit HORIZONTAL)
    cam.clip_start, cam.clip_end = near, far
    ob = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(ob)
    scene.camera = ob
    frames = np.linspace(1, FRAMES, len(keys))
    for frame, (loc, target) in zip(frames, keys):
        _aim(ob, loc, target)
        ob.keyframe_insert("location", frame=float(frame))
        ob.keyframe_insert("rotation_euler", frame=float(frame))
    _linear(ob)
    scene.frame_set(1)
    return ob


def _linear(ob):
    ad = ob.animation_data
    if ad is None or ad.action is None:
        return
    curves = getattr(ad.action, "fcurves", None)
    if curves is None:  # 5.0 layered actions
        curves = [fc for layer in ad.action.layers for strip in layer.strips
                  for bag in strip.channelbags for fc in bag.fcurves]
    for fc in curves:
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


def _aim(ob, loc, target):
    from mathutils import Vector
    ob.location = loc
    d = Vector(target) - Vector(loc)
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def add_sun(scene, direction, name="Sun", energy=3.0):
    """A sun whose light travels along ``direction``."""
    from mathutils import Vector
    lt = bpy.data.lights.new(name, "SUN")
    lt.energy = energy
    lt.angle = 0.0
    ob = bpy.data.objects.new(name, lt)
    scene.collection.objects.link(ob)
    ob.rotation_euler = Vector(direction).normalized().to_track_quat("-Z", "Y").to_euler()
    return ob


def add_spot(scene, loc, target, cone_deg, energy=2000.0, name="Spot"):
    lt = bpy.data.lights.new(name, "SPOT")
    lt.energy = energy
    lt.spot_size = math.radians(cone_deg)
    lt.spot_blend = 0.0
    lt.shadow_soft_size = 0.0
    ob = bpy.data.objects.new(name, lt)
    scene.collection.objects.link(ob)
    _aim(ob, loc, target)
    return ob


def _socket(sockets, name, kind=None):
    cands = [s for s in sockets if s.name == name]
    if kind is not None:
        typed = [s for s in cands if s.type == kind]
        enabled = [s for s in typed if getattr(s, "enabled", True)]
        cands = enabled or typed or cands
    return cands[0]


def scatter_modifier(ob, instance_obj, count, lo, hi, seed, scale_lo, scale_hi, name):
    """Geometry nodes on ``ob``: ``count`` points at random (x, y) in [lo, hi] (z = 0),
    one instance of ``instance_obj`` on each with random Z rotation and scale in
    [scale_lo, scale_hi] (vectors). Outputs instances only (small .blend)."""
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    gin = nodes.new("NodeGroupInput")
    gout = nodes.new("NodeGroupOutput")
    pts = nodes.new("GeometryNodePoints")
    pts.inputs["Count"].default_value = int(count)

    def rand_vec(lo_v, hi_v, s):
        r = nodes.new("FunctionNodeRandomValue")
        r.data_type = "FLOAT_VECTOR"
        _socket(r.inputs, "Min", "VECTOR").default_value = lo_v
        _socket(r.inputs, "Max", "VECTOR").default_value = hi_v
        _socket(r.inputs, "Seed", "INT").default_value = s
        return _socket(r.outputs, "Value", "VECTOR")

    links.new(rand_vec((lo[0], lo[1], 0.0), (hi[0], hi[1], 0.0), seed), pts.inputs["Position"])
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = instance_obj
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(pts.outputs["Points"], iop.inputs["Points"])
    links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    links.new(rand_vec((0, 0, 0), (0, 0, 2 * math.pi), seed + 1), iop.inputs["Rotation"])
    links.new(rand_vec(scale_lo, scale_hi, seed + 2), iop.inputs["Scale"])
    links.new(iop.outputs["Instances"], gout.inputs[0])
    mod = ob.modifiers.new(name, "NODES")
    mod.node_group = tree
    return mod


def _hide_source(ob):
    """Keep an instanced source object out of renders and shadows (it sits off-stage)."""
    ob.hide_render = True
    ob.hide_viewport = False
    ob.location = (0.0, 0.0, -1000.0)


# ---------------------------------------------------------------- scenes

def build_tiny() -> bpy.types.Scene:
    """A 10 m ground, a 1 m cube 1 m above it, a sun from above-side: for tests."""
    scene = reset()
    scene.render.resolution_x, scene.render.resolution_y = 96, 64
    mesh_object("Ground", *grid([-5, 5], [-5, 5]))
    mesh_object("Cube", *box((-0.5, -0.5, 1.0), (0.5, 0.5, 2.0)))
    add_sun(scene, (0.3, 0.2, -1.0))
    add_camera(scene, [((0, -8, 6), (0, 0, 0.5)), ((1, -8, 6), (0, 0, 0.5))], fov_deg=60, near=0.5, far=30)
    return scene


def build_forest() -> bpy.types.Scene:
    """Scherzer's outdoor setup: 10,000 trees scattered by geometry nodes, fov 60°, near 0.1, far 70."""
    scene = reset()
    mesh_object("Ground", *grid(np.linspace(-160, 160, 3), np.linspace(-160, 160, 3)))
    crown = lathe([(1.0, 1.1), (0.0, 4.0)], segments=8)
    trunk = lathe([(0.12, 0.0), (0.12, 1.2)], segments=5)
    tree = mesh_object("Tree", *merge([crown, trunk]))
    scatter = mesh_object("Forest", np.zeros((0, 3)), [])
    scatter_modifier(scatter, tree, 10000, (-150, -150), (150, 150), seed=7,
                     scale_lo=(0.7, 0.7, 0.6), scale_hi=(1.3, 1.3, 1.5), name="Scatter trees")
    _hide_source(tree)
    add_sun(scene, (0.8, -0.45, -0.5))
    add_camera(scene, [((-20, -40, 9), (0, -10, 2)), ((-12, -34, 9), (8, -4, 2))], fov_deg=60, near=0.1, far=70)
    return scene


def _pawn(c):
    return lathe([(0.0, 0.0), (0.32, 0.0), (0.3, 0.08), (0.15, 0.2), (0.12, 0.45), (0.2, 0.5),
                  (0.18, 0.62), (0.2, 0.7), (0.14, 0.82), (0.0, 0.86)], 12, c)


def _rook(c):
    return lathe([(0.0, 0.0), (0.36, 0.0), (0.34, 0.1), (0.22, 0.2), (0.2, 0.8), (0.3, 0.85),
                  (0.3, 1.05), (0.0, 1.05)], 12, c)


def _king(c):
    body = lathe([(0.0, 0.0), (0.38, 0.0), (0.34, 0.12), (0.2, 0.3), (0.15, 1.0), (0.28, 1.1),
                  (0.22, 1.3), (0.0, 1.32)], 12, c)
    cross = box((c[0] - 0.05, c[1] - 0.05, c[2] + 1.3), (c[0] + 0.05, c[1] + 0.05, c[2] + 1.6))
    bar = box((c[0] - 0.15, c[1] - 0.05, c[2] + 1.43), (c[0] + 0.15, c[1] + 0.05, c[2] + 1.5))
    return merge([body, cross, bar])


def build_chess() -> bpy.types.Scene:
    """PSM Fig. 1: a chessboard with pieces under a spot light, seen from close to the board."""
    scene = reset()
    squares = [box((i - 4 + 0.01, j - 4 + 0.01, 0.0), (i - 3 - 0.01, j - 3 - 0.01, 0.04 if (i + j) % 2 else 0.06))
               for i in range(8) for j in range(8)]
    mesh_object("Board", *merge(squares))
    mesh_object("Table", *box((-12, -12, -0.3), (12, 12, 0.0)))
    pieces = []
    for i in range(8):
        for row in (1, 6):
            pieces.append(_pawn((i - 3.5, row - 3.5, 0.05)))
    for i, maker in enumerate([_rook, _pawn, _pawn, _king, _king, _pawn, _pawn, _rook]):
        for row in (0, 7):
            pieces.append(maker((i - 3.5, row - 3.5, 0.05)))
    mesh_object("Pieces", *merge(pieces))
    add_spot(scene, (4.0, -6.0, 9.0), (0.0, 0.0, 0.0), cone_deg=70)
    add_camera(scene, [((-1.5, -5.6, 1.1), (0.5, 0.5, 0.4)), ((0.5, -5.8, 1.2), (1.0, 0.5, 0.4))],
               fov_deg=70, near=0.1, far=30)
    return scene


def build_floor_wall() -> bpy.types.Scene:
    """Lixel §4: a floor and a wall with objects on both, under a sun."""
    scene = reset()
    mesh_object("Floor", *grid(np.linspace(-10, 10, 2), np.linspace(-4, 16, 2)))
    wall_v, wall_f = grid(np.linspace(-10, 10, 2), np.linspace(0, 6, 2))
    wall_v = wall_v[:, [0, 2, 1]] + np.array([0, 6.0, 0])   # the plane y = 6, z in [0, 6]
    mesh_object("Wall", wall_v, [tuple(reversed(f)) for f in wall_f])
    parts = [box((-3, 1, 0), (-1.8, 2.2, 1.2)), box((2, 3, 0), (2.6, 3.6, 2.4)), sphere(0.8, (0.5, 0.5, 0.8)),
             lathe([(0.0, 0.0), (0.4, 0.0), (0.55, 0.5), (0.3, 1.1), (0.35, 1.5), (0.0, 1.5)], 16, (-4.5, 3.5, 0)),
             box((-6, 5.4, 2.5), (-2, 6.0, 2.6)),               # a shelf on the wall
             box((-5.5, 5.5, 2.6), (-5.0, 5.9, 3.4)), sphere(0.3, (-3.0, 5.7, 2.9)),
             box((1, 5.9, 2), (3.5, 6.0, 4)), box((1.2, 5.85, 2.2), (3.3, 5.9, 3.8)),   # a picture frame
             box((5, 5.2, 0), (7, 6, 3.5))]                      # a cupboard against the wall
    mesh_object("Objects", *merge(parts))
    add_sun(scene, (0.55, 0.6, -0.5))
    add_camera(scene, [((-3.5, -3.5, 3.2), (0, 4, 1.2)), ((-0.5, -3.8, 2.8), (1, 4, 1.2))], fov_deg=65, near=0.1, far=60)
    return scene


def _terrain_height(x, y):
    return (18 * np.sin(x / 120.0) * np.cos(y / 160.0) + 9 * np.sin(x / 47.0 + 1.3) * np.sin(y / 61.0)
            + 0.0002 * (x * x))


def build_terrain() -> bpy.types.Scene:
    """GMNPR §4: long-range terrain with a town, fov 60°, near 1, far 800."""
    scene = reset()
    xs = np.linspace(-800, 800, 121)
    ys = np.linspace(-500, 1100, 121)
    mesh_object("Terrain", *grid(xs, ys, _terrain_height))
    rng = np.random.default_rng(11)
    n = 1500
    px = rng.uniform(-400, 400, n)
    py = rng.uniform(-250, 700, n)
    pts = np.column_stack([px, py, _terrain_height(px, py) - 1.0])
    town = mesh_object("Town points", pts, [])
    house = mesh_object("House", *merge([box((-0.5, -0.5, 0), (0.5, 0.5, 1.0)),
                                         lathe([(0.75, 1.0), (0.0, 1.5)], 4)]))
    _instance_on_vertices(town, house, seed=5, scale_lo=(8, 8, 5), scale_hi=(18, 18, 25))
    _hide_source(house)
    add_sun(scene, (0.6, 0.35, -0.45))
    add_camera(scene, [((-60, -420, 70), (0, 0, 0)), ((-20, -380, 70), (40, 40, 0))], fov_deg=60, near=1.0, far=800)
    return scene


def _instance_on_vertices(ob, instance_obj, seed, scale_lo, scale_hi):
    tree = bpy.data.node_groups.new("Instance on vertices", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = instance_obj
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(gin.outputs[0], iop.inputs["Points"])
    links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    for inp, lo, hi, s in (("Rotation", (0, 0, 0), (0, 0, 2 * math.pi), seed), ("Scale", scale_lo, scale_hi, seed + 1)):
        r = nodes.new("FunctionNodeRandomValue")
        r.data_type = "FLOAT_VECTOR"
        _socket(r.inputs, "Min", "VECTOR").default_value = lo
        _socket(r.inputs, "Max", "VECTOR").default_value = hi
        _socket(r.inputs, "Seed", "INT").default_value = s
        links.new(_socket(r.outputs, "Value", "VECTOR"), iop.inputs[inp])
    links.new(iop.outputs["Instances"], gout.inputs[0])
    mod = ob.modifiers.new("Instance on vertices", "NODES")
    mod.node_group = tree


def build_telephoto() -> bpy.types.Scene:
    """A street through a 200 mm lens (about 10° horizontal): the narrow-FOV case."""
    scene = reset()
    mesh_object("Street", *grid(np.linspace(-40, 40, 2), np.linspace(-300, 420, 2)))
    rng = np.random.default_rng(3)
    parts = []
    for side in (-1, 1):
        y = -120.0
        while y < 400:
            depth = rng.uniform(8, 20)
            height = rng.uniform(8, 30)
            x0 = side * 9.0
            x1 = side * rng.uniform(20, 30)
            parts.append(box((min(x0, x1), y, 0), (max(x0, x1), y + depth - 0.5, height)))
            y += depth
        for y in np.arange(-115, 400, 25):                      # street lamps: pole and arm
            x = side * 7.5
            parts.append(box((x - 0.1, y - 0.1, 0), (x + 0.1, y + 0.1, 6)))
            parts.append(box((min(x, x - side * 2), y - 0.06, 5.8), (max(x, x - side * 2), y + 0.06, 5.95)))
    for y in rng.uniform(-110, 380, 40):                      # cars
        x = rng.choice([-4.0, 4.0]) + rng.uniform(-0.5, 0.5)
        parts.append(box((x - 0.9, y, 0.2), (x + 0.9, y + 4.2, 1.4)))
        parts.append(box((x - 0.8, y + 1.0, 1.4), (x + 0.8, y + 3.0, 2.0)))
    mesh_object("Town", *merge(parts))
    add_sun(scene, (0.55, 0.25, -0.8))
    add_camera(scene, [((0.0, -260, 6), (0, 150, 2)), ((1.5, -255, 6), (0.5, 150, 2))],
               lens=200, near=50, far=700)
    return scene


BUILDERS = {
    "forest": build_forest,
    "chess": build_chess,
    "floor_wall": build_floor_wall,
    "terrain": build_terrain,
    "telephoto": build_telephoto,
}
"""The committed sample scenes, in report order (``tiny`` is built on demand for tests)."""
