"""What the viewport overlays draw, as plain numpy arrays (no bpy, no gpu).

The draw handlers in :mod:`.overlays` only upload these arrays, so everything
drawn can be checked in background mode against the warp core: B's faces are the
:class:`~addon.warp.body.IntersectionBody` faces, the light frusta are the clip
volumes of the maps' matrices (inverse projection of the unit cube; where one
reaches through infinity, its part around B: :func:`map_volume`), the warp
frustum P is ``Diagnostics.warp_frustum_corners``.

Also here: the footprint readout of the panel, from ``addon.measure.footprint``.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..warp.body import RELATIVE_TOLERANCE
from ..warp.geometry import clip_halfspaces, finite_clip_volume_corners, normalize
from ..warp.polyhedron import HEXAHEDRON_EDGES, ConvexPolytope, unit_halfspaces
from ..warp.types import Light, ShadowSetup, View


EXTRA_PROJECTION_CENTRE = ("projection_centre", "projection_center", "eye", "warp_eye")
EXTRA_V_P = ("v_p", "V_P", "warp_direction", "view_dir_projected")
EXTRA_MIDDLE_VECTOR = ("middle_vector", "middle", "body_middle_vector")

VOLUME_MARGIN = 0.25
"""A map's volume that reaches through infinity is drawn within B's box grown by this fraction of the box's
diagonal on every side: enough to show it leaving B, little enough to keep the picture on the scene."""


def fan_triangles(faces) -> np.ndarray:
    """(T, 3, 3) triangles of convex planar polygons (each (K, 3)), fanned from
    their first vertex."""
    tris = [np.stack([f[0], f[i], f[i + 1]]) for f in faces for i in range(1, len(f) - 1)]
    return np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3)


def polygon_edges(faces) -> np.ndarray:
    """(E, 2, 3) boundary segments of polygons, each shared edge once."""
    seen, out = set(), []
    for f in faces:
        k = len(f)
        for i in range(k):
            a, b = np.asarray(f[i], dtype=np.float64), np.asarray(f[(i + 1) % k], dtype=np.float64)
            key = tuple(sorted((tuple(np.round(a, 9)), tuple(np.round(b, 9)))))
            if key in seen:
                continue
            seen.add(key)
            out.append((a, b))
    return np.asarray(out, dtype=np.float64).reshape(-1, 2, 3)


def hexahedron_lines(corners) -> np.ndarray:
    """(12, 2, 3) edges of a frustum given as 8 corners (``UNIT_CUBE_CORNERS`` order)."""
    c = np.asarray(corners, dtype=np.float64).reshape(8, 3)
    return c[HEXAHEDRON_EDGES]


def drawing_bound(points) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the box of ``points`` grown by ``VOLUME_MARGIN`` of its diagonal on every side."""
    p = np.concatenate([np.asarray(q, dtype=np.float64).reshape(-1, 3) for q in points])
    lo, hi = p.min(axis=0), p.max(axis=0)
    grow = VOLUME_MARGIN * max(float(np.linalg.norm(hi - lo)), 1e-9)
    return lo - grow, hi + grow


def map_volume(matrix, bound) -> Optional[ConvexPolytope]:
    """The world points a map's ``matrix`` covers, its clip volume (``warp.geometry.clip_halfspaces``): the
    hexahedron of its 8 corners where it is bounded; where it reaches through infinity (a corner at w <= 0, which
    the divide by w would mirror to the wrong side), its part inside the box ``bound`` = (lo, hi). None when
    nothing with volume is left."""
    corners = finite_clip_volume_corners(matrix)
    if corners is not None:
        try:
            return ConvexPolytope.hexahedron(corners, RELATIVE_TOLERANCE * float(np.ptp(corners, axis=0).max()))
        except ValueError:                     # a face without area: a flat volume
            return None
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bound)
    box = ConvexPolytope.box(lo, hi, RELATIVE_TOLERANCE * float(np.linalg.norm(hi - lo)))
    return box.clip(*unit_halfspaces(*clip_halfspaces(matrix)))


def volume_lines(volume: Optional[ConvexPolytope]) -> np.ndarray:
    """(E, 2, 3) edges of a ``map_volume`` (none for None)."""
    return volume.vertices[volume.edges] if volume is not None else np.zeros((0, 2, 3))


def _extra_vector(extra: dict, names) -> Optional[np.ndarray]:
    for n in names:
        v = extra.get(n)
        if v is None:
            continue
        a = np.asarray(v, dtype=np.float64).reshape(-1)
        if a.shape == (3,) and np.all(np.isfinite(a)):
            return a
        if a.shape == (4,) and np.all(np.isfinite(a)) and abs(a[3]) > 1e-300:
            return a[:3] / a[3]
    return None


def body_extent(body_faces, fallback: float = 1.0) -> float:
    if not body_faces:
        return fallback
    p = np.concatenate([np.asarray(f) for f in body_faces])
    return float(max(np.linalg.norm(p.max(axis=0) - p.min(axis=0)), 1e-9))


def overlay_geometry(view: View, setup: Optional[ShadowSetup], body_faces=None) -> dict:
    """Everything the line/triangle overlays draw, in world space (float64).

    Keys:
      ``body_triangles`` (T, 3, 3) and ``body_edges`` (E, 2, 3): B (Scherzer §4.1);
      ``view_corners`` (8, 3) and ``view_lines`` (12, 2, 3): the camera's frustum V;
      ``light_faces``, per map, the faces ((K, 3) outward loops; none when flat) and ``light_lines``
      (E, 2, 3) the edges of its volume (``map_volume``; 12 per map when bounded, else its part inside
      ``drawing_bound`` of B's faces, or of V's corners without B);
      ``warp_corners`` (8, 3) or None and ``warp_lines``: the warp frustum P (Scherzer §4.4);
      ``points`` dict name -> (3,): the projection centre, B's centroid;
      ``vectors`` dict name -> (2, 3) segment: V_P and B's middle vector from B's centroid
      (or the projection centre), scaled to B's size;
      ``splits``: a cascade's splits, nearest first, each a dict of ``body_edges`` (its
      own B), ``light_lines`` (its maps' volumes) and ``view_lines`` (its slab of V),
      each (E, 2, 3); the cascade's maps are drawn there and not in ``light_lines``.
    ``body_faces``: B as convex polygons (``IntersectionBody.faces``); when None,
    nothing of B is drawn.
    """
    faces = list(body_faces) if body_faces is not None else []
    out: dict = {
        "body_triangles": fan_triangles(faces),
        "body_edges": polygon_edges(faces),
        "view_corners": view.corners(),
        "light_faces": [],
        "warp_corners": None,
        "points": {},
        "vectors": {},
    }
    bound = drawing_bound(faces or [view.corners()])
    volumes = [map_volume(m.matrix, bound) for m in setup.maps] if setup is not None else []
    out["splits"] = split_geometry(view, setup, volumes)
    out["view_lines"] = hexahedron_lines(out["view_corners"])
    light_lines = []
    if setup is not None:
        for volume in volumes:
            out["light_faces"].append(volume.faces() if volume is not None else [])
            if not out["splits"]:              # a cascade's maps are drawn with their splits
                light_lines.append(volume_lines(volume))
        diag = setup.diagnostics
        if diag.warp_frustum_corners is not None:
            wc = np.asarray(diag.warp_frustum_corners, dtype=np.float64).reshape(8, 3)
            if np.all(np.isfinite(wc)):
                out["warp_corners"] = wc
        extent = body_extent(faces, fallback=float(np.linalg.norm(view.corners()[7] - view.corners()[0])) * 0.1)
        centre = np.concatenate(faces).mean(axis=0) if faces else None
        eye = _extra_vector(diag.extra, EXTRA_PROJECTION_CENTRE)
        if eye is not None:
            out["points"]["projection_centre"] = eye
        if centre is not None:
            out["points"]["body_centroid"] = centre
        origin = centre if centre is not None else eye
        if origin is not None:
            for key, names in (("v_p", EXTRA_V_P), ("middle_vector", EXTRA_MIDDLE_VECTOR)):
                d = _extra_vector(diag.extra, names)
                if d is not None and np.linalg.norm(d) > 0:
                    start = eye if (key == "v_p" and eye is not None) else origin
                    out["vectors"][key] = np.stack([start, start + normalize(d) * extent * 0.5])
    out["light_lines"] = (np.concatenate(light_lines) if light_lines else np.zeros((0, 2, 3)))
    out["warp_lines"] = hexahedron_lines(out["warp_corners"]) if out["warp_corners"] is not None else np.zeros((0, 2, 3))
    return out


def split_geometry(view: View, setup: Optional[ShadowSetup], volumes: list) -> list:
    """A cascade's splits (``overlay_geometry``'s ``splits``): each split's B,
    the edges of its maps' ``volumes`` (``map_volume``, one per map) and its slab
    of the view frustum; [] for other setups."""
    extra = setup.diagnostics.extra if setup is not None else {}
    if "map_splits" not in extra:
        return []
    from ..warp.partition.splits import split_view
    depths, owner, faces = extra["splits"], np.asarray(extra["map_splits"]), extra["split_body_faces"]
    out = []
    for i, (near, far) in enumerate(zip(depths[:-1], depths[1:])):
        maps = [volume_lines(volumes[k]) for k in np.flatnonzero(owner == i)]
        out.append({
            "body_edges": polygon_edges(faces[i]) if faces[i] is not None else np.zeros((0, 2, 3)),
            "light_lines": np.concatenate(maps) if maps else np.zeros((0, 2, 3)),
            "view_lines": hexahedron_lines(split_view(view, near, far).corners()),
        })
    return out


# --- texel footprint readout ----------------------------------------------------------------------------------

def footprint_estimate(setup: ShadowSetup, view: View, light: Light, points) -> Optional[dict]:
    """Median and maximum texel footprint (screen pixels spanned by one texel,
    ``addon.measure.footprint``) over world ``points`` (e.g. samples of the
    visible part R of B), each point in the map that serves it. The surface at
    each point is taken to face halfway between the camera and the light, so
    the estimate shows perspective aliasing without the projection aliasing of
    surfaces grazing the light or the camera (Stamminger-Drettakis §1.1: the
    cos β / cos α factor is then 1). None when no point is served."""
    from ..measure.footprint import setup_footprints
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0 or setup is None or not setup.maps:
        return None
    to_camera = view.position[None, :] - p
    to_camera /= np.maximum(np.linalg.norm(to_camera, axis=1, keepdims=True), 1e-300)
    to_light = -light.rays_to(p)
    normals = to_camera + to_light
    keep = (np.linalg.norm(normals, axis=1) > 1e-9) & np.all(np.isfinite(normals), axis=1)
    p, normals = p[keep], normals[keep]
    idx = setup.map_index(p, view, tol=1e-6)
    linear, _area = setup_footprints(view, setup, p, normals, map_index=idx)
    ok = np.isfinite(linear)
    if not ok.any():
        return None
    return {"median": float(np.median(linear[ok])), "max": float(linear[ok].max()), "count": int(ok.sum())}
