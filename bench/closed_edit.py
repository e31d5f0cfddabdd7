"""What editing a large closed mesh costs Lixel's scene cache per edit, with the
closedness test run at once (as before) and left until the edits stop (now).

    python -m bench.closed_edit                     # 1M triangles, 15 repeats
    python -m bench.closed_edit --tris 200000 --repeat 9

Scene: one mesh of ``--tris`` triangles that bounds solids (a field of boxes,
one mesh, quads). Two edits, as the viewport sees them (each re-reads the mesh,
``GeometryCache.update``), then the read the next frame's draw makes of
``MeshData.bounds_solids`` (``pipeline.seen_from_outside``):

* ``move``: one vertex moved (the triangles stay: the closed parts are kept,
  the volumes were tested again);
* ``topology``: one quad's triangulation turned (new triangles: the whole
  closedness test, one sort of every edge, ran again).

Per edit, two caches see the same new content, interleaved, in alternating
order: ``at_once`` (``GeometryCache(defer_solids=False)``, the behaviour
before) and ``deferred`` (the default: a mesh re-read after an edit is drawn
whole until an update finds it unchanged). ``settle`` is what the deferred
cache pays once the edits stop: the first update that finds the mesh unchanged,
and the test it then runs. Medians over the repeats of each variant's wall time
(ms) and of the per-repeat ratio deferred / at_once.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

_scratch = tempfile.mkdtemp(prefix="lixel-bench-")
os.environ.setdefault("XDG_CACHE_HOME", os.path.join(_scratch, "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_scratch, "blender-user"))

import numpy as np  # noqa: E402


def box_field(bpy, n_tris: int):
    """One mesh object of about ``n_tris`` triangles: closed boxes with outward faces, as quads."""
    from bench.gpu_pipeline import _mesh
    n = max(n_tris // 12, 1)
    rng = np.random.default_rng(5)
    centre = np.c_[rng.uniform(-45, 45, (n, 2)), np.zeros(n)]
    size = np.c_[rng.uniform(0.2, 1.0, (n, 2)), rng.uniform(0.5, 4.0, n)]
    corners = np.array([(x, y, z) for z in (0.0, 1.0) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
    faces = np.array([(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)])
    return _mesh(bpy, "Boxes", (corners[None] * size[:, None] + centre[:, None]).reshape(-1, 3),
                 (faces[None] + 8 * np.arange(n)[:, None, None]).reshape(-1, 4))


def edit(bpy, ob, kind: str, step: int) -> None:
    me = ob.data
    if kind == "move":
        me.vertices[0].co.z += 1e-3 * (1 if step % 2 else -1)
    else:                      # turn quad 0's corners by one: the other diagonal, still closed and outwards
        loops = me.polygons[0].loop_indices
        verts = [me.loops[i].vertex_index for i in loops]
        for i, v in zip(loops, verts[1:] + verts[:1]):
            me.loops[i].vertex_index = v
    me.update(calc_edges=kind != "move")


def run(args) -> dict:
    import bpy

    from addon.scene.geometry import GeometryCache
    scene = bpy.data.scenes.new("closed_edit")
    ob = box_field(bpy, args.tris)
    scene.collection.objects.link(ob)
    bpy.context.window.scene = scene
    dg = bpy.context.evaluated_depsgraph_get()
    caches = {"at_once": GeometryCache(defer_solids=False), "deferred": GeometryCache()}

    def frame(cache):
        """One viewport update after an edit and the draw's read of every mesh's closedness."""
        t = time.perf_counter()
        geometry = cache.update(dg)
        solids = [m.bounds_solids for m in geometry.meshes.values()]
        return (time.perf_counter() - t) * 1e3, solids

    for cache in caches.values():
        assert frame(cache)[1] == [True], "the box field bounds solids"
    out = {}
    for kind in ("move", "topology"):
        times = {"at_once": [], "deferred": [], "settle": []}
        for step in range(args.repeat):
            edit(bpy, ob, kind, step)
            dg.update()
            order = ("at_once", "deferred") if step % 2 else ("deferred", "at_once")
            for name in order:
                ms, solids = frame(caches[name])
                times[name].append(ms)
                assert solids == ([True] if name == "at_once" else [False])
            ms, solids = frame(caches["deferred"])       # the edits stopped: the next update finds it unchanged
            times["settle"].append(ms)
            assert solids == [True]
        ratio = statistics.median(d / a for d, a in zip(times["deferred"], times["at_once"]))
        out[kind] = {**{k: statistics.median(v) for k, v in times.items()}, "ratio": ratio,
                     "min": {k: min(v) for k, v in times.items()}, "max": {k: max(v) for k, v in times.items()}}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.closed_edit", description=__doc__.split("\n\n")[0])
    p.add_argument("--tris", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=15)
    p.add_argument("--json", help="also write the numbers here")
    args = p.parse_args(argv)
    out = run(args)
    print(f"{args.tris:,} triangles, {args.repeat} edits each; medians (ms), min..max")
    print(f"{'edit':10s} {'at once':>20s} {'deferred':>20s} {'settle':>20s} {'deferred/at once':>17s}")
    for kind, row in out.items():
        cells = [f"{row[k]:7.1f} ({row['min'][k]:.1f}..{row['max'][k]:.1f})" for k in ("at_once", "deferred", "settle")]
        print(f"{kind:10s} {cells[0]:>20s} {cells[1]:>20s} {cells[2]:>20s} {row['ratio']:17.2f}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"tris": args.tris, "repeat": args.repeat, **out}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
