"""Planes of interest from Blender for the plane-optimal method (Chong & Gortler,
"A Lixel for every Pixel", §3: "the environment's author must choose the
desired planes of interest", e.g. a floor, a wall, a table top).

Three sources, all returning :class:`addon.warp.plane_map.PlaneOfInterest`
(world-space unit normal, offset and the convex extent of the faces):

* :func:`planes_from_selected_faces` - the selected faces of mesh objects
  (Edit Mode selections are synced first), coplanar faces merged into one plane;
* :func:`planes_from_objects` - for each object, its largest flat face group
  (the plane of a Plane object, the top of a table slab);
* :func:`detect_planes` - automatic: the large planar surfaces of the visible
  meshes, ranked by the share of the camera image they cover, no more than
  ``max_planes`` and none covering less than ``min_coverage`` of the image.

:func:`as_warp_planes` turns them into ``WarpOptions.planes`` entries
(point, normal, extent). Imports bpy only inside the functions that need it;
the geometry is numpy float64.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..warp.plane_map import PlaneOfInterest, clip_polygon, convex_polygon_on_plane
from ..warp.body import view_frustum
from ..warp.polyhedron import Plane
from ..warp.types import View, WarpError

log = logging.getLogger(__name__)

COPLANAR_ANGLE = 1e-3
"""Faces whose normals differ by less than this (radians) ..."""
COPLANAR_DISTANCE = 1e-5
"""... and whose planes are within this fraction of the object's size are one plane."""
MAX_GROUPS = 32
"""Coplanar groups looked at per object (largest first)."""
DETECT_MIN_COVERAGE = 0.1
"""detect_planes: a plane must cover at least this share of the camera image."""
DETECT_MAX_PLANES = 3
"""detect_planes: at most this many planes (each costs a shadow-map pass)."""


@dataclass
class FaceSet:
    """World-space faces of one object: ``centres``, unit ``normals`` and ``areas``
    (F,), and each face's world vertices (``loops`` indexes ``points`` from
    ``starts[i]`` for ``counts[i]``)."""

    name: str
    centres: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    points: np.ndarray
    loop_vertices: np.ndarray
    starts: np.ndarray
    counts: np.ndarray
    size: float

    def face_points(self, faces: np.ndarray) -> np.ndarray:
        idx = np.concatenate([self.loop_vertices[s:s + c] for s, c in zip(self.starts[faces], self.counts[faces])])
        return self.points[idx]


def mesh_faces(obj, depsgraph=None, selected_only: bool = False) -> FaceSet | None:
    """The world-space faces of a mesh object (evaluated if ``depsgraph`` is
    given, the selection of the original mesh when ``selected_only``)."""
    if obj is None or obj.type != "MESH":
        return None
    if selected_only and obj.mode == "EDIT":
        obj.update_from_editmode()
    src = obj.evaluated_get(depsgraph) if depsgraph is not None and not selected_only else obj
    mesh = src.data
    nf = len(mesh.polygons)
    if nf == 0:
        return None
    nv, nl = len(mesh.vertices), len(mesh.loops)
    co = np.empty(nv * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    loop_v = np.empty(nl, dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loop_v)
    starts = np.empty(nf, dtype=np.int64)
    counts = np.empty(nf, dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", counts)
    keep = np.ones(nf, dtype=bool)
    if selected_only:
        sel = np.zeros(nf, dtype=bool)
        mesh.polygons.foreach_get("select", sel)
        keep = sel
    m = np.array(src.matrix_world, dtype=np.float64)
    pts = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    # world normals and areas from the world-space polygons (Newell), robust to any scale/shear
    first = loop_v[starts]
    normals = np.zeros((nf, 3))
    for k in range(int(counts.max())):
        live = counts > k
        a = pts[loop_v[starts[live] + k]]
        b = pts[loop_v[starts[live] + (k + 1) % counts[live]]]
        normals[live] += np.cross(a - pts[first[live]], b - pts[first[live]])
    areas = 0.5 * np.linalg.norm(normals, axis=1)
    ok = keep & (areas > 0)
    if not ok.any():
        return None
    normals = normals / np.maximum(2 * areas, 1e-300)[:, None]
    sums = np.zeros((nf, 3))
    np.add.at(sums, np.repeat(np.arange(nf), counts), pts[loop_v])
    centres = sums / counts[:, None]
    idx = np.where(ok)[0]
    size = float(np.linalg.norm(np.ptp(pts, axis=0))) or 1.0
    return FaceSet(obj.name, centres[idx], normals[idx], areas[idx], pts, loop_v, starts[idx], counts[idx], size)


def coplanar_groups(faces: FaceSet, max_groups: int = MAX_GROUPS) -> list[PlaneOfInterest]:
    """Faces merged into planes, largest total area first: a group is every face
    whose normal is within COPLANAR_ANGLE of the group's largest face and whose
    centre lies within COPLANAR_DISTANCE x the object size of its plane. The
    extent is the convex hull of the group's vertices on the plane."""
    n, c, a = faces.normals, faces.centres, faces.areas
    free = np.ones(len(a), dtype=bool)
    cos = np.cos(COPLANAR_ANGLE)
    dist = COPLANAR_DISTANCE * faces.size
    groups = []
    total = float(a.sum())
    while free.any() and len(groups) < max_groups:
        seed = int(np.flatnonzero(free)[np.argmax(a[free])])
        members = free & (n @ n[seed] > cos) & (np.abs((c - c[seed]) @ n[seed]) <= dist)
        free &= ~members
        ids = np.flatnonzero(members)
        w = a[ids]
        normal = (n[ids] * w[:, None]).sum(axis=0)
        normal /= np.linalg.norm(normal)
        offset = float((c[ids] @ normal * w).sum() / w.sum())
        pts = faces.face_points(ids)
        pts = pts - np.outer(pts @ normal - offset, normal)
        extent = convex_polygon_on_plane(pts, normal, 1e-9 * faces.size)
        if extent is not None:
            groups.append((float(w.sum()), PlaneOfInterest(normal, offset, extent, f"{faces.name} ({len(ids)} faces)")))
        if a[free].sum() < 1e-3 * total:
            break
    groups.sort(key=lambda g: (-g[0], -float(g[1].normal[2])))
    return [p for _, p in groups]


def merge_planes(planes: list[PlaneOfInterest], scale: float) -> list[PlaneOfInterest]:
    """Planes that are the same plane (normals within COPLANAR_ANGLE, offsets
    within COPLANAR_DISTANCE x ``scale``) become one, extents joined."""
    out: list[PlaneOfInterest] = []
    cos = np.cos(COPLANAR_ANGLE)
    for p in planes:
        for i, q in enumerate(out):
            if p.normal @ q.normal > cos and abs(p.offset - q.offset) <= COPLANAR_DISTANCE * scale:
                ext = None
                if p.extent is not None and q.extent is not None:
                    pts = np.concatenate([p.extent, q.extent])
                    pts = pts - np.outer(pts @ q.normal - q.offset, q.normal)
                    ext = convex_polygon_on_plane(pts, q.normal, 1e-9 * scale)
                out[i] = PlaneOfInterest(q.normal, q.offset, ext, f"{q.name} + {p.name}")
                break
        else:
            out.append(p)
    return out


def planes_from_selected_faces(objects) -> list[PlaneOfInterest]:
    """One plane per set of coplanar selected faces of the given mesh objects."""
    planes, scale = [], 1.0
    for ob in objects:
        fs = mesh_faces(ob, selected_only=True)
        if fs is None:
            continue
        scale = max(scale, fs.size)
        planes.extend(coplanar_groups(fs))
    return merge_planes(planes, scale)


def planes_from_objects(objects, depsgraph=None) -> list[PlaneOfInterest]:
    """For each mesh object its largest flat face group (ties: the most upward-facing)."""
    planes, scale = [], 1.0
    for ob in objects:
        fs = mesh_faces(ob, depsgraph)
        if fs is None:
            continue
        groups = coplanar_groups(fs, max_groups=8)
        if groups:
            scale = max(scale, fs.size)
            planes.append(groups[0])
    return merge_planes(planes, scale)


def image_coverage(plane: PlaneOfInterest, view: View) -> float:
    """The share of the camera image the plane's extent covers (frustum-clipped,
    projected; occlusion is not considered)."""
    if plane.extent is None:
        return 0.0
    origin = view.position
    poly = np.asarray(plane.extent, dtype=np.float64) - origin
    frustum = view_frustum(view, origin)
    for n, o in zip(frustum.normals, frustum.offsets):
        poly = clip_polygon(poly, Plane(n, float(o)), 0.0)
        if len(poly) < 3:
            return 0.0
    h = np.column_stack([poly + origin, np.ones(len(poly))]) @ view.world_to_clip.T
    xy = h[:, :2] / h[:, 3:4]
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1))) / 4.0


def detect_planes(depsgraph, view: View, max_planes: int = DETECT_MAX_PLANES,
                  min_coverage: float = DETECT_MIN_COVERAGE) -> list[PlaneOfInterest]:
    """The large planar receivers visible in the view: every visible mesh's
    coplanar face groups, merged across objects, ranked by the share of the
    image they cover; the first ``max_planes`` covering at least
    ``min_coverage`` each. Empty when there is none (plane_optimal then uses its
    default plane)."""
    candidates, scale = [], 1.0
    for ob in depsgraph.objects:
        if ob.type != "MESH":
            continue
        fs = mesh_faces(ob.original if hasattr(ob, "original") else ob, depsgraph)
        if fs is None:
            continue
        scale = max(scale, fs.size)
        candidates.extend(coplanar_groups(fs))
    candidates = merge_planes(candidates, scale)
    scored = sorted(((image_coverage(p, view), i, p) for i, p in enumerate(candidates)), key=lambda t: (-t[0], t[1]))
    chosen = [p for cov, _, p in scored if cov >= min_coverage][:max_planes]
    log.debug("detect_planes: %d candidates, chose %s", len(candidates), [p.name for p in chosen])
    return chosen


def as_warp_planes(planes: list[PlaneOfInterest]) -> tuple:
    """``WarpOptions.planes`` entries (point, normal, extent)."""
    if not planes:
        return ()
    out = []
    for p in planes:
        if not isinstance(p, PlaneOfInterest):
            raise WarpError(f"not a plane of interest: {p!r}")
        out.append((p.point, p.normal, p.extent))
    return tuple(out)
