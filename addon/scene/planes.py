"""Planes of interest from Blender meshes for the plane-optimal method (Chong & Gortler,
"A Lixel for every Pixel", §3: "the environment's author must choose the desired planes
of interest", e.g. a floor, a wall, a table top). The one place that turns faces into
planes; the operator ``lixel.planes_from_selection`` is a thin caller.

* :func:`planes_from_selected_faces` - the selected faces of mesh objects (Edit Mode
  selections are synced first), coplanar faces merged into one plane;
* :func:`planes_from_objects` - for each object, its largest flat face group (the plane
  of a subdivided or triangulated floor, the top of a table slab).

Both return :class:`addon.warp.plane_map.PlaneOfInterest` (world-space unit normal, offset
and the convex extent of the faces, usable as ``WarpOptions.planes`` entries) and raise
:class:`NoPlane` naming an object whose faces give no plane. Without planes the warp side
chooses its own (``plane_map.default_plane``: the flat receiver top the camera sees most).
Imports bpy only through the objects it is given; the geometry is numpy float64.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..warp.plane_map import PlaneOfInterest
from ..warp.polyhedron import convex_polygon_on_plane

COPLANAR_ANGLE = 1e-3
"""Faces whose normals differ by less than this (radians; either orientation) ... Mesh
vertices are float32, so the faces of one flat surface differ by about ulp(|coordinate|) /
face size. Measured on tilted grids (bpy 5.0.1 polygon normals and float64 Newell normals
alike): 1.7e-7 for an 8x8 grid 20 m wide, 1.1e-5 for 300x300 cells triangulated 2 km wide,
1.8e-4 for a 20 m floor of 0.2 m triangles whose vertices lie 2.8 km from the origin (an
imported survey: 1e-4 split it). 1e-3 keeps 5x above that and still parts a 0.06° fold."""
COPLANAR_DISTANCE = COPLANAR_ANGLE
"""... and whose centres lie within this fraction of the object's size of the plane are one
plane: a normal off by COPLANAR_ANGLE misses a face across the object by that much (1e-5
split the 2.8 km floor above into 5 planes)."""
MAX_GROUPS = 32
"""Coplanar groups looked at per object (seeded by its largest faces first)."""


class NoPlane(ValueError):
    """An object whose considered faces give no plane: non-finite vertex coordinates or no area."""

    def __init__(self, name: str):
        super().__init__(f"{name} has no plane (non-finite vertex coordinates, or no area): "
                         f"fix its vertices or select another face")


@dataclass
class FaceSet:
    """World-space faces of one object: ``centres``, unit ``normals`` and ``areas``
    (F,), and each face's world vertices (``loop_vertices`` indexes ``points`` from
    ``starts[i]`` for ``counts[i]``); ``size`` the object's diagonal."""

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
        return self.points[np.unique(idx)]


def mesh_faces(obj, depsgraph=None, selected_only: bool = False) -> FaceSet | None:
    """The world-space faces of a mesh object with area (evaluated if ``depsgraph`` is
    given, the selection of the original mesh when ``selected_only``); None when it has
    no face (or none selected); :class:`NoPlane` when a considered face is not finite or
    none has area (a zero-scale object, collapsed faces)."""
    if obj is None or obj.type != "MESH":
        return None
    if selected_only and obj.mode == "EDIT":
        obj.update_from_editmode()
    src = obj.evaluated_get(depsgraph) if depsgraph is not None and not selected_only else obj
    mesh = src.data
    nf = len(mesh.polygons)
    keep = np.ones(nf, dtype=bool)
    if selected_only and nf:
        mesh.polygons.foreach_get("select", keep)
    if not keep.any():
        return None
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    loop_v = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loop_v)
    starts = np.empty(nf, dtype=np.int64)
    counts = np.empty(nf, dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", counts)
    m = np.array(src.matrix_world, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
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
    if not np.isfinite(areas[keep]).all() or not ok.any():
        raise NoPlane(obj.name)
    normals = normals / np.maximum(2 * areas, 1e-300)[:, None]
    sums = np.zeros((nf, 3))
    np.add.at(sums, np.repeat(np.arange(nf), counts), pts[loop_v])
    centres = sums / counts[:, None]
    idx = np.flatnonzero(ok)
    size = float(np.linalg.norm(np.ptp(pts[np.isfinite(pts).all(axis=1)], axis=0))) or 1.0
    return FaceSet(obj.name, centres[idx], normals[idx], areas[idx], pts, loop_v, starts[idx], counts[idx], size)


def coplanar_groups(faces: FaceSet, max_groups: int = MAX_GROUPS) -> list[PlaneOfInterest]:
    """Faces merged into planes, largest total area first (ties: the most upward-facing):
    a group is every face whose normal is within COPLANAR_ANGLE of the group's largest
    face, either way round, and whose centre lies within COPLANAR_DISTANCE x the object
    size of its plane; it faces the way its largest face does. The extent is the convex
    hull of the group's vertices on the plane."""
    n, c, a = faces.normals, faces.centres, faces.areas
    free = np.ones(len(a), dtype=bool)
    cos = np.cos(COPLANAR_ANGLE)
    groups = []
    total = float(a.sum())
    while free.any() and len(groups) < max_groups:
        seed = int(np.flatnonzero(free)[np.argmax(a[free])])
        along = n @ n[seed]
        members = free & (np.abs(along) > cos) & (np.abs((c - c[seed]) @ n[seed]) <= COPLANAR_DISTANCE * faces.size)
        free &= ~members
        ids = np.flatnonzero(members)
        w = a[ids] * np.sign(along[ids])
        normal = (n[ids] * w[:, None]).sum(axis=0)
        normal /= np.linalg.norm(normal)
        offset = float((c[ids] @ normal * np.abs(w)).sum() / np.abs(w).sum())
        pts = faces.face_points(ids)
        pts = pts - np.outer(pts @ normal - offset, normal)
        extent = convex_polygon_on_plane(pts, normal, 1e-9 * faces.size)
        if extent is not None:
            name = f"{faces.name} ({len(ids)} face{'s' if len(ids) > 1 else ''})"
            groups.append((float(a[ids].sum()), PlaneOfInterest(normal, offset, extent, name)))
        if a[free].sum() < 1e-3 * total:
            break
    groups.sort(key=lambda g: (-g[0], -float(g[1].normal[2])))
    return [p for _, p in groups]


def merge_planes(planes: list[PlaneOfInterest], scale: float) -> list[PlaneOfInterest]:
    """Planes that are the same plane (normals within COPLANAR_ANGLE either way round,
    offsets within COPLANAR_DISTANCE x ``scale``) become the first of them, extents joined."""
    out: list[PlaneOfInterest] = []
    cos = np.cos(COPLANAR_ANGLE)
    for p in planes:
        for i, q in enumerate(out):
            way = float(np.sign(p.normal @ q.normal))
            if abs(p.normal @ q.normal) > cos and abs(way * p.offset - q.offset) <= COPLANAR_DISTANCE * scale:
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
        if fs is not None:
            scale = max(scale, fs.size)
            planes.extend(coplanar_groups(fs))
    return merge_planes(planes, scale)


def planes_from_objects(objects, depsgraph=None) -> list[PlaneOfInterest]:
    """For each mesh object its largest flat face group (ties: the most upward-facing),
    the same plane from several objects merged."""
    planes, scale = [], 1.0
    for ob in objects:
        fs = mesh_faces(ob, depsgraph)
        groups = [] if fs is None else coplanar_groups(fs)
        if groups:
            scale = max(scale, fs.size)
            planes.append(groups[0])
    return merge_planes(planes, scale)
