"""addon.scene.geometry: triangles from the evaluated depsgraph."""
import importlib

import bpy
import numpy as np
import pytest


@pytest.fixture(scope="module")
def geom(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.scene.geometry")


@pytest.fixture
def scene(fresh_scene):
    yield fresh_scene


def mesh(scene, name, verts, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    ob = bpy.data.objects.new(name, me)
    scene.collection.objects.link(ob)
    return ob


def depsgraph(scene):
    dg = scene.view_layers[0].depsgraph
    dg.update()
    return dg


def tri_area(pos, tris):
    p = pos.astype(np.float64)
    return 0.5 * np.linalg.norm(np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]), axis=1).sum()


def test_quads_triangles_and_concave_quads_keep_their_area(geom, scene):
    # A concave quad (dart): only the diagonal through the reflex corner (index 3) is right.
    dart = [(0, 0, 0), (2, 1, 0), (0, 2, 0), (0.5, 1, 0)]
    ob = mesh(scene, "Dart", dart + [(3, 0, 0), (4, 0, 0), (3, 1, 0)], [(0, 1, 2, 3), (4, 5, 6)])
    # The dart's corners start at a convex corner, so a blind 0-2 split would be wrong.
    got = geom.read_object(ob.evaluated_get(depsgraph(scene)))
    pos, tris, _ = got
    assert tris.shape == (3, 3)
    expect = sum(p.area for p in ob.data.polygons)
    assert tri_area(pos, tris) == pytest.approx(expect, rel=1e-6)


def test_ngons_use_blenders_triangulation(geom, scene):
    # An L-shaped hexagon (concave n-gon).
    ob = mesh(scene, "L", [(0, 0, 0), (2, 0, 0), (2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0)], [(0, 1, 2, 3, 4, 5)])
    pos, tris, _ = geom.read_object(ob.evaluated_get(depsgraph(scene)))
    assert len(tris) == 4
    assert tri_area(pos, tris) == pytest.approx(3.0, rel=1e-6)


def test_modifiers_are_applied_and_the_cache_reuses_meshes(geom, scene):
    ob = mesh(scene, "Quad", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2, 3)])
    twin = bpy.data.objects.new("Twin", ob.data)  # shares the mesh: one batch for both
    scene.collection.objects.link(twin)
    twin.location.x = 5
    sub = ob.modifiers.new("sub", "SUBSURF")
    sub.levels = 2
    sub.subdivision_type = "SIMPLE"
    cache = geom.GeometryCache()
    g = cache.update(depsgraph(scene))
    keys = set(g.instances.keys)
    assert ("OB", "Quad") in keys and ("ME", "Quad") in keys
    assert g.meshes[("OB", "Quad")].triangle_count == 32  # 16 quads after two simple subdivisions
    assert g.meshes[("ME", "Quad")].triangle_count == 2
    assert cache.extractions == 2
    g2 = cache.update(depsgraph(scene))
    assert cache.extractions == 2 and cache.reused == 2
    assert g2.meshes[("OB", "Quad")] is g.meshes[("OB", "Quad")]
    sub.levels = 1
    g3 = cache.update(depsgraph(scene))
    assert cache.extractions == 3 and g3.meshes[("OB", "Quad")].triangle_count == 8
    assert g3.meshes[("OB", "Quad")].version == 2


def test_geometry_nodes_instances_share_one_mesh(geom, scene):
    host = mesh(scene, "Host", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    ng = bpy.data.node_groups.new("lixel_geom_test", "GeometryNodeTree")
    try:
        ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        go = ng.nodes.new("NodeGroupOutput")
        grid = ng.nodes.new("GeometryNodeMeshGrid")
        grid.inputs["Vertices X"].default_value = 5
        grid.inputs["Vertices Y"].default_value = 4
        cube = ng.nodes.new("GeometryNodeMeshCube")
        iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
        ng.links.new(grid.outputs["Mesh"], iop.inputs["Points"])
        ng.links.new(cube.outputs["Mesh"], iop.inputs["Instance"])
        ng.links.new(iop.outputs["Instances"], go.inputs[0])
        host.modifiers.new("gn", "NODES").node_group = ng
        g = geom.GeometryCache().update(depsgraph(scene))
        assert len(g.instances) == 20
        assert len(set(g.instances.keys)) == 1
        assert g.triangle_count == 20 * 12
        assert len({tuple(m[:3, 3]) for m in g.instances.matrices}) == 20  # matrices copied, all distinct
    finally:
        bpy.data.node_groups.remove(ng)


def test_text_objects_are_triangulated(geom, scene):
    curve = bpy.data.curves.new("Txt", "FONT")
    curve.body = "L"
    ob = bpy.data.objects.new("Txt", curve)
    scene.collection.objects.link(ob)
    g = geom.GeometryCache().update(depsgraph(scene))
    assert ("OB", "Txt") in g.meshes and g.meshes[("OB", "Txt")].triangle_count > 0


def test_cache_forgets_meshes_unused_for_a_while(geom, scene):
    ob = mesh(scene, "Gone", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    keep = mesh(scene, "Kept", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    cache = geom.GeometryCache()
    cache.update(depsgraph(scene))
    assert ("ME", "Gone") in cache.meshes
    ob.hide_viewport = True
    for _ in range(cache.KEEP_UNUSED):
        cache.update(depsgraph(scene))
    assert ("ME", "Gone") in cache.meshes  # hidden for a while: still cached
    cache.update(depsgraph(scene))
    assert ("ME", "Gone") not in cache.meshes and ("ME", "Kept") in cache.meshes
    assert keep.name == "Kept"


def _scatter(host, instance_obj, as_instance: bool, count=6):
    """Geometry nodes on ``host``: ``count`` points, each an instance of ``instance_obj``'s
    geometry (or of the object itself, ``as_instance``), randomly turned and scaled."""
    ng = bpy.data.node_groups.new("lixel_scatter_test", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = ng.nodes, ng.links
    gin, go = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    pts = nodes.new("GeometryNodePoints")
    pts.inputs["Count"].default_value = count
    rnd = nodes.new("FunctionNodeRandomValue")
    rnd.data_type = "FLOAT_VECTOR"
    links.new(rnd.outputs[0], pts.inputs["Position"])
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = instance_obj
    info.inputs["As Instance"].default_value = as_instance
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(pts.outputs["Points"], iop.inputs["Points"])
    links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    links.new(rnd.outputs[0], iop.inputs["Rotation"])
    join = nodes.new("GeometryNodeJoinGeometry")
    links.new(iop.outputs["Instances"], join.inputs[0])
    links.new(gin.outputs[0], join.inputs[0])       # the host's own mesh is drawn too
    links.new(join.outputs[0], go.inputs[0])
    host.modifiers.new("scatter", "NODES").node_group = ng
    return ng


def _instance_rows(inst):
    return sorted((k, tuple(np.round(m, 5).ravel()), bool(c), bool(r))
                  for k, m, c, r in zip(inst.keys, inst.matrices, inst.casts, inst.receives))


def test_array_reader_reads_what_the_walk_reads(geom, scene):
    """Blender 4.3+: geometry-nodes instances read as arrays (instances_pointcloud)
    give the same instances, keys, matrices, visibility and boxes as the walk over
    depsgraph.object_instances, for geometry instances, object instances (nested),
    mirrored and moved instancers and plain objects."""
    inst_mod = importlib.import_module(geom.__name__.rsplit(".", 1)[0] + ".instances")
    if not inst_mod.fast_reader_available():
        pytest.skip("Object.evaluated_geometry is Blender 4.3+")
    tree = mesh(scene, "Tree", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 2)], [(0, 1, 2), (0, 1, 3), (1, 2, 3)])
    tree.visible_shadow = False
    host = mesh(scene, "Host", [(0, 0, 0), (4, 0, 0), (4, 4, 0)], [(0, 1, 2)])
    host.location = (10, -3, 1)
    host.scale = (1, -2, 1)                      # mirrors: the instances' matrices go through it
    other = mesh(scene, "Other", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    other.visible_camera = False
    trees = _scatter(host, tree, as_instance=False)
    objects = _scatter(other, tree, as_instance=True, count=4)
    sub = tree.modifiers.new("sub", "SUBSURF")
    sub.levels = 1
    try:
        dg = depsgraph(scene)
        fast = inst_mod.read_instances(dg)
        walk = inst_mod.walk_instances(dg)
        assert fast is not None and len(fast) == len(walk) == 1 + 1 + 1 + 6 + 4
        assert _instance_rows(fast) == _instance_rows(walk)
        boxes = lambda s: {k: tuple(np.round(b, 5).ravel()) for k, b in zip(s.key_list, s.key_boxes)}  # noqa: E731
        assert boxes(fast) == boxes(walk)
        gc = geom.GeometryCache()
        g = gc.update(dg)
        assert g.triangle_count == sum(gc.meshes[k].triangle_count for k in walk.keys)
    finally:
        bpy.data.node_groups.remove(trees)
        bpy.data.node_groups.remove(objects)


def test_array_reader_leaves_particles_to_the_walk(geom, scene):
    inst_mod = importlib.import_module(geom.__name__.rsplit(".", 1)[0] + ".instances")
    box = mesh(scene, "Box", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    empty = bpy.data.objects.new("Group", None)
    coll = bpy.data.collections.new("lixel_group_test")
    coll.objects.link(box)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = coll
    scene.collection.objects.link(empty)
    try:
        dg = depsgraph(scene)
        assert inst_mod.read_instances(dg) is None
        g = geom.GeometryCache().update(dg)
        assert len(g.instances) == 2    # the box and its collection instance, through the walk
    finally:
        bpy.data.collections.remove(coll)


def test_an_unchanged_scene_gives_the_same_instance_set_and_a_change_a_new_one(geom, scene):
    """Only what changed is redone: the cache hands out the same InstanceSet (so
    its bounds and culling index) while nothing changed, and a new one when an
    instance transform inside a node tree or an object's matrix changes."""
    tree = mesh(scene, "Tree", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 2)], [(0, 1, 2), (0, 1, 3), (1, 2, 3)])
    host = mesh(scene, "Host", [(0, 0, 0), (4, 0, 0), (4, 4, 0)], [(0, 1, 2)])
    ng = _scatter(host, tree, as_instance=False, count=50)
    try:
        cache = geom.GeometryCache()
        g1 = cache.update(depsgraph(scene))
        g2 = cache.update(depsgraph(scene))
        assert g2 is g1 and g2.instances.bounds is g1.instances.bounds and cache.instance_sets == 1
        seed = next(n for n in ng.nodes if n.bl_idname == "FunctionNodeRandomValue")
        seed.inputs["Seed"].default_value = 5
        g3 = cache.update(depsgraph(scene))
        assert g3.instances is not g1.instances and cache.instance_sets == 2
        assert not np.array_equal(g3.instances.matrices, g1.instances.matrices)
        host.location.z += 1.0
        g4 = cache.update(depsgraph(scene))
        assert g4.instances is not g3.instances and cache.instance_sets == 3
        moved = np.abs(g4.instances.matrices[:, 2, 3] - g3.instances.matrices[:, 2, 3] - 1.0) < 1e-6
        assert moved.sum() == 1 + 50      # the host and its instances; the tree object stays
        assert cache.extractions == 3   # tree geometry, host: read once; the instances' mesh read once
    finally:
        bpy.data.node_groups.remove(ng)


def test_a_mesh_edited_in_place_gives_new_bounds(geom, scene):
    """Vertices moved without moving the object (edit mode, a script, another file's
    mesh of the same name) make a new InstanceSet with the mesh's new box: B and the
    culling are made from it, and a stale box loses or invents shadows."""
    ob = mesh(scene, "Slab", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1, 2)])
    cache = geom.GeometryCache()
    g1 = cache.update(depsgraph(scene))
    for v in ob.data.vertices:
        v.co.z += 3.0
    ob.data.update()
    g2 = cache.update(depsgraph(scene))
    assert g2.instances is not g1.instances
    np.testing.assert_allclose(g2.instances.world_box_array[0], [[0, 0, 3], [1, 1, 3]])
