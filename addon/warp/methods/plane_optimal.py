"""Plane-optimal shadow maps: Chong & Gortler, "A Lixel for every Pixel" (EGSR 2004): one map per plane of interest,
exact on that plane (§2), then the uniform fallback maps (§3). The steps and Lixel's readings of §2: docs/papers.md."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..body import IntersectionBody
from ..diagnostics import Diagnostics
from ..fit import window_matrix
from ..frame import NEAR_FLOOR, light_frames
from ..geometry import cross, homogeneous, translation
from ..linear_depth import fitted_row
from ..plane_map import (FLAT_RATIO, PlaneOfInterest, clip_to_polygon, corner_ray_points, default_plane,
                         enclosing_polygon, flattest_box, is_convex_polygon, min_area_twist, offset_directions,
                         plane_light_matrix, polygon_area, rotation2d)
from ..polyhedron import Edges, convex_polygon_on_plane, plane_section, section_points
from ..types import MAX_MAP_SIDE, Light, Region, ShadowMap, ShadowSetup, View, WarpError, WarpOptions
from .common import body_diagnostics, frame_maps, near_plane_notes

MAX_REGION_VERTICES = 32
"""A region polygon has at most this many vertices (the shader's limit,
``addon.gpu.shaders.MAX_POLYGON``); a larger one is replaced by an enclosing one."""
MAX_MAPS = 8
"""Maps one shading pass can select from (``addon.gpu.shaders.MAX_MAPS``): plane
maps beyond what this leaves next to the fallback maps are left out, smallest first."""
REGION_TOLERANCE = 1e-6
"""A point belongs to a plane's region within this fraction of B's scale (at least 100x the body tolerance)."""
TWIST_GAIN = 0.99
"""plane_twist='auto' twists when the rotated rectangle is below this fraction
of the unrotated one and the budget forces fewer lixels than pixels."""


@dataclasses.dataclass
class PlaneMap:
    """One plane's map while the budget is shared out (relative to the camera)."""

    index: int
    plane: PlaneOfInterest
    polygon: np.ndarray          # the needed polygon on P
    rows: np.ndarray             # 3x4: x, y, w rows; on P they equal the viewer's clip x, y, w
    pixel: np.ndarray            # 3x3: viewer clip (x, y, w) -> pixel (px, py, 1)
    height: np.ndarray           # 4-vector: height above P on the light's side, h(x) = height · (x, 1)
    fit_h: np.ndarray            # (N, 4) region slab + casters, homogeneous: all inside the map's clip volume
    depth: tuple                 # the least and greatest -h / w over fit_h (the map's z / w before its window)
    pixels: list                 # (x, y) pixel coordinates of the tolerance-grown polygon
    info: dict
    twist: float = 0.0
    rect: tuple = (0, 0, 1, 1)   # (i0, j0, i1, j1) in texels of the scaled, twisted image


def plane_optimal(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    diag = body_diagnostics("plane_optimal", view, light, body)
    origin = view.position
    tol = max(REGION_TOLERANCE * body.scale, 100 * body.tolerance)
    planes, share = planes_of_interest(options, body, tol, diag)
    jobs = [j for j in (plane_map_of(k, p, view, light, body, origin, tol, diag) for k, p in enumerate(planes))
            if j is not None]
    frames = light_frames(view, light, body, options)
    room = MAX_MAPS - len(frames)
    if len(jobs) > room:
        ranked = sorted(jobs, key=lambda j: -j.info["pixel_area"])
        for j in ranked[max(room, 0):]:
            diag.fallback(f"plane:{j.index}", f"{j.plane.name}: at most {MAX_MAPS} maps fit one shading pass "
                                              f"({len(frames)} fallback maps); its map is left out, smallest first")
        jobs = sorted(ranked[:max(room, 0)], key=lambda j: j.index)
    total = options.shadow_map_size[0] * options.shadow_map_size[1]
    s = share_budget(jobs, options.plane_budget * total, options.plane_twist)
    if jobs and not worth_its_texels(share, s, sum(_texels(j.rect) for j in jobs), len(frames) * total):
        diag.fallback("plane:0", f"{jobs[0].plane.name}: {share:.1%} of the edges (or seen pixels), not worth its texels"
                                 + ("" if s >= 1.0 else f" ({s:.3g} lixels per pixel: below one its lixels sample no "
                                                        f"pixel's own point)"))
        jobs = []
    maps = [light_map(j, s, origin, tol, options) for j in jobs]
    used = sum(m.size[0] * m.size[1] for m in maps)
    size = _fallback_size(max(total - used / len(frames), 1), options)
    for m in frame_maps(frames, size, options.texel_snapping, options.linear_z):
        m.role = "fallback" if len(frames) == 1 else f"fallback:{m.role}"
        maps.append(m)
    diag.fallbacks += near_plane_notes(frames, "fallback:")
    diag.extra["planes"] = [{
        "role": f"plane:{j.index}", "name": j.plane.name, "normal": j.plane.normal, "offset": j.plane.offset,
        "lixels_per_pixel": s, "twist_deg": math.degrees(j.twist), "rect": list(j.rect),
        "pixel_area": j.info["pixel_area"], "condition": j.info["condition"], "residual": j.info["residual"],
    } for j in jobs]
    diag.extra["budget"] = {
        "plane_budget": options.plane_budget, "seen_share": share, "total_texels": total, "plane_texels": used,
        "one_lixel_texels": sum(_texels(r) for r in _rects(jobs, 1.0)) if jobs else 0,
        "plane_share": used / total, "fallback_sizes": [list(size) for _ in frames], "fallback_maps": len(frames),
        "lixels_per_pixel": s if jobs else None,
    }
    diag.extra["frames"] = [m.role for m in maps]
    return ShadowSetup(maps, diag)


# ---------------------------------------------------------------------------
# The planes of interest.
# ---------------------------------------------------------------------------

def planes_of_interest(options: WarpOptions, body: IntersectionBody, tol: float,
                       diag: Diagnostics) -> tuple[list[PlaneOfInterest], float | None]:
    """``WarpOptions.planes``, else the flat receiver top the camera sees most (``plane_map.default_plane``; without a
    seen surface the widest); and its share of the errors (None: unknown, or planes given): where the first look found
    shadow edges (``VisibleRegion.edge_directions``), of the samples at them, where shadow aliasing is (§1; as many as
    the uniform map errs there, its texels' width across them), even above its share of the seen pixels; else that."""
    if options.planes:
        return [PlaneOfInterest.from_option(p, i) for i, p in enumerate(options.planes)], None
    surface, edges = (None, None) if body.visible is None else (body.visible.surface, body.visible.edge_directions)
    plane, share = default_plane(body.culled.receivers.boxes, surface, tol, None if edges is None else edges.any(1))
    if plane is None:
        diag.fallback("planes", _no_default_plane(body.culled.receivers.boxes, surface is not None))
        return [], None
    diag.extra.update(default_plane=plane.name, seen_share=share)
    return [plane], share


def worth_its_texels(share: float | None, s: float, texels: int, budget: float) -> bool:
    """Whether a map at ``s`` lixels per pixel holding ``share`` of uniform's errors is worth ``texels`` of the
    fallbacks' ``budget``: texel-wide errors leave (1 - σ)·√(budget / (budget - texels)) of uniform's (those off the
    plane at the fallback's wider texels), σ the share made exact: all at one lixel per pixel (§2), none below."""
    exact = share if s >= 1.0 else 0.0
    return share is None or (1.0 - exact) ** 2 <= 1.0 - texels / budget


def _no_default_plane(receiver_boxes, seen: bool) -> str:
    """Why no receiver gives a default plane (a fallback note)."""
    flattest = flattest_box(receiver_boxes)
    if flattest is None:
        found = "no receiver box is in view"
    elif seen and default_plane(receiver_boxes)[0] is not None:
        found = "the camera sees no flat receiver's top (a floor, a table top)"
    else:
        i, height, side = flattest
        found = (f"no receiver in view is flat (a plane of interest needs a box at most {FLAT_RATIO:.0%} as high as "
                 f"its smaller side; the flattest, receiver box {i}, is {height / side:.0%}): not planar, e.g. terrain")
    return (f"no plane of interest given and {found}. plane_optimal renders with its fallback map alone, the "
            f"uniform map with the whole texel budget (Chong-Gortler §5: where no plane describes the receivers "
            f"the method has nothing to be exact on); give planes (Planes of Interest in the Lixel panel, or "
            f"\"planes\" in the config) to add plane maps")


# ---------------------------------------------------------------------------
# One plane's map (§2), relative to the camera (``origin``).
# ---------------------------------------------------------------------------

def plane_map_of(k: int, plane: PlaneOfInterest, view: View, light: Light, body: IntersectionBody,
                 origin: np.ndarray, tol: float, diag: Diagnostics) -> PlaneMap | None:
    """Plane k's map but its rectangle, §2's steps in order; None (with a recorded fallback) when it can have none."""
    role = f"plane:{k}"
    pi = plane.vector(origin)                                 # π, relative to the camera
    l_h = np.array(light.homogeneous_from(origin))
    height, why = height_above(plane, pi, l_h, tol, body.scale)
    if why is None and seen_edge_on(view, pi, origin, tol, body.scale):
        why = f"{plane.name} passes through the camera (seen edge-on): it covers no pixel"
    polygon = needed_polygon(plane, pi, body, origin) if why is None else None
    if why is None and (polygon is None or polygon_area(polygon, plane.normal) <= tol * tol):
        why = (f"{plane.name} has no visible part (behind the camera, outside the view, the spot cone or the "
               f"receivers' bounds)")
    if why is None:
        try:
            m, info = plane_light_matrix(corner_ray_points(view.corners() - origin, pi), l_h, body.scale)
            rows = scaled_to_view_w(m, view, polygon.sum(axis=0) / len(polygon), origin)
            if rows is None:
                why = f"{plane.name}: the needed part is not in front of the camera"
        except WarpError as exc:
            why = f"{plane.name}: {exc}"
    if why is not None:
        diag.fallback(role, why)
        return None
    # The region (what Region.contains accepts) and the points its map's clip volume holds.
    outwards = offset_directions(polygon, plane.normal)
    grown = polygon + tol * outwards
    casters, near_clamped = casters_of(polygon, outwards, grown, height, l_h, tol, body, origin)
    if near_clamped:
        diag.fallback(f"{role}: near plane", "the light is inside B; casters nearer than 1e-6 of B's scale "
                                             "to the light's height are not in the plane map")
    fit_h = homogeneous(np.concatenate([grown - tol * plane.normal, grown + tol * plane.normal, casters]))
    h, w = np.array([height, rows[2]]) @ fit_h.T           # height, and clip w (the z row is -h before its window)
    if not (w > 0).all():
        diag.fallback(role, "some casters are behind the plane map's centre of projection and were left out")
        fit_h, h, w = fit_h[w > 0], h[w > 0], w[w > 0]
    pixel = np.array([[view.resolution[0] / 2, 0.0, view.resolution[0] / 2],
                      [0.0, view.resolution[1] / 2, view.resolution[1] / 2], [0.0, 0.0, 1.0]])
    pixels = homogeneous(grown) @ (pixel @ rows).T
    pixels = (pixels[:, :2] / pixels[:, 2:]).tolist()                 # (a few: plain floats)
    area = polygon_area(np.c_[pixels, np.zeros(len(pixels))], (0.0, 0.0, 1.0))
    if area < 1.0:
        diag.fallback(role, f"{plane.name} covers less than one pixel of the view ({area:.3g})")
        return None
    depth = (-float((h / w).max()), -float((h / w).min()))
    info = dict(info, pixel_area=float(area), near_clamped=near_clamped)
    return PlaneMap(k, plane, polygon, rows, pixel, height, fit_h, depth, pixels, info)


def height_above(plane: PlaneOfInterest, pi: np.ndarray, l_h: np.ndarray, tol: float,
                 scale: float) -> tuple[np.ndarray, str | None]:
    """h, the height above P towards the light (h(x) = h · (x, 1)), or why the plane
    can have no map (the light in its plane)."""
    light_side = float(pi @ l_h)
    if abs(light_side) <= (1e-9 if l_h[3] == 0 else max(tol, 1e-9 * scale)):
        what = "the sun shines along" if l_h[3] == 0 else "the light lies in"
        return pi, (f"{what} {plane.name}: every light ray reaching it grazes it, so no plane map exists; the "
                    f"fallback map serves it")
    return math.copysign(1.0, light_side) * pi, None


def seen_edge_on(view: View, pi: np.ndarray, origin: np.ndarray, tol: float, scale: float) -> bool:
    """Whether P passes through the camera's centre of projection (a direction for an orthographic camera)."""
    if view.orthographic:
        return abs(float(pi[:3] @ view.direction)) <= 1e-9
    return abs(float(pi @ np.append(view.position - origin, 1.0))) <= max(tol, 1e-9 * scale)


def needed_polygon(plane: PlaneOfInterest, pi: np.ndarray, body: IntersectionBody,
                   origin: np.ndarray) -> np.ndarray | None:
    """Less of the plane (§2, Fig. 6): P ∩ R within the plane's extent, at most
    MAX_REGION_VERTICES (else an enclosing polygon), relative to ``origin``; None: nothing left."""
    n, shift = plane.normal, body.origin - origin          # (R's frame to ours: none when both are the camera's)
    region = body.visible_polytope if not shift.any() else body.visible_polytope.translated(shift)
    polygon = plane_section(region, n, -float(pi[3]))
    if polygon is not None and plane.extent is not None:
        extent = plane.extent - origin
        if not is_convex_polygon(extent, n, body.tolerance):      # (a box's top, a hull: already their own hull)
            extent = convex_polygon_on_plane(extent, n, body.tolerance)
        polygon = None if extent is None else clip_to_polygon(polygon, extent, n, body.tolerance)
    if polygon is not None and len(polygon) > MAX_REGION_VERTICES:
        polygon = enclosing_polygon(polygon, n, MAX_REGION_VERTICES)
    return polygon


def scaled_to_view_w(m: np.ndarray, view: View, centre: np.ndarray, origin: np.ndarray) -> np.ndarray | None:
    """Sign and scale (Fig. 5): M's x, y, w rows scaled so that w is the viewer's clip
    w on the plane (at ``centre``); None when that part is not in front of the camera."""
    w_view = float(view.world_to_clip[3, :3] @ (centre + origin) + view.world_to_clip[3, 3])
    w_light = float(m[3, :3] @ centre + m[3, 3])
    return m[[0, 1, 3]] * (w_view / w_light) if w_view > 0 and abs(w_light) > 0 else None


# ---------------------------------------------------------------------------
# The casters of a plane's region: B ∩ C.
# ---------------------------------------------------------------------------

def casters_of(polygon: np.ndarray, outwards: np.ndarray, grown: np.ndarray, height: np.ndarray, l_h: np.ndarray,
               tol: float, body: IntersectionBody, origin: np.ndarray) -> tuple[np.ndarray, bool]:
    """B ∩ C, the points of B on the needed rays (§2, Fig. 5-6), C the cone (a prism for a sun) from the light
    over the region; the flag: a point light inside B, casters within ``frame.NEAR_FLOOR`` of its height left out."""
    corners = polygon + tol * (2 + min(steepest_incidence(grown, height, l_h), 1e12)) * outwards
    normals, offsets = cone_facets(corners, height, l_h, tol)
    b_poly = body.polytope_from(origin)
    if len(normals) == len(corners) + 1:                             # (every side plane made)
        points, _ = section_points(b_poly, normals[None], offsets[None], cone_edges(corners, height, l_h, tol), 0.0)
    else:
        part = b_poly.clip(normals, offsets)
        points = None if part is None else part.vertices
    if points is None or not len(points):
        return np.zeros((0, 3)), False
    if l_h[3] != 0:
        top = float(height @ l_h) / l_h[3] - NEAR_FLOOR * body.scale
        if float((points @ height[:3]).max()) + height[3] > top:
            part = b_poly.clip(np.vstack([normals, height[:3]]), np.append(offsets, top - height[3]))
            return (np.zeros((0, 3)) if part is None else part.vertices), True
    return points, False


def steepest_incidence(points: np.ndarray, height: np.ndarray, l_h: np.ndarray) -> float:
    """tan α of the steepest light ray reaching ``points`` (α from P's normal)."""
    rays = -l_h[None, :3] if l_h[3] == 0 else points - l_h[:3] / l_h[3]
    along = np.abs(rays @ height[:3])                                           # |ray| cos α
    across = np.sqrt(np.maximum(np.einsum("ij,ij->i", rays, rays) - along * along, 0.0))   # |ray| sin α
    return float((across / np.maximum(along, 1e-300)).max(initial=0.0))


def cone_facets(corners: np.ndarray, height: np.ndarray, l_h: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """C's facets as unit normals and offsets: h(x) >= -tol and a side plane through
    each edge of ``corners`` and the light (none for an edge pointing at it)."""
    edges = np.concatenate([corners[1:], corners[:1]]) - corners
    sides = cross(edges, l_h[:3] - corners * l_h[3])                  # each edge x (from its start towards the light)
    length = np.sqrt(np.einsum("ij,ij->i", sides, sides))
    made = length > 0
    sides = sides[made] / length[made, None]
    offsets = np.einsum("ij,ij->i", sides, corners[made])
    outwards = np.where(sides @ corners.mean(axis=0) > offsets, -1.0, 1.0)        # (the centre on the inner side)
    return np.vstack([-height[:3], sides * outwards[:, None]]), np.append(tol + height[3], offsets * outwards)


def cone_edges(corners: np.ndarray, height: np.ndarray, l_h: np.ndarray, tol: float) -> Edges:
    """C's edges as one body's ``Edges``: from each base corner (h = -tol) one up to
    the light (unbounded for a sun) and one to the next base corner."""
    rise = float(height[:3] @ l_h[:3])            # height . l_h = rise + h0·lw: the light's (homogeneous) height
    k = len(corners)
    if l_h[3] == 0:                               # towards the sun along l: h rises by ``rise`` per unit
        base = corners - (tol / rise) * l_h[:3]
        up, up_ends = l_h[None, :3].repeat(k, axis=0), [math.inf] * k
    else:                                         # q = c + (tol / H)(c - light), H the light's height (h(c) = 0)
        light = l_h[:3] / l_h[3]
        base = corners + (tol / (rise / l_h[3] + height[3])) * (corners - light)
        up, up_ends = light - base, [1.0] * k
    along = np.concatenate([base[1:], base[:1]]) - base
    return Edges(np.concatenate([base, base])[None], np.concatenate([up, along])[None], np.array([up_ends + [1.0] * k]))


# ---------------------------------------------------------------------------
# The budget: lixels per pixel, twists and rectangles (§2, §3).
# ---------------------------------------------------------------------------

def share_budget(jobs: list[PlaneMap], budget: float, twist_mode: str) -> float:
    """The common lixels per pixel s (1 when it fits ``budget`` texels, else the
    largest s < 1 that does, §2) and each map's twist and rectangle."""
    if not jobs:
        return 1.0
    for j in jobs:
        j.twist = 0.0
    need = sum(map(_texels, _rects(jobs, 1.0)))
    if twist_mode == "on" or (twist_mode == "auto" and need > budget):
        _choose_twists(jobs, always=twist_mode == "on")
    s = _fraction_of_a_lixel(jobs, budget)
    for j, r in zip(jobs, _rects(jobs, s)):
        j.rect = r
    return s


def lixel_of_pixel(s: float, theta: float) -> np.ndarray:
    """ℓ = s·R(θ)·(p - ½) (3x3): at s = 1 and no twist every pixel centre lands on a
    lixel centre (§2: "exactly one lixel ... samples the exact same geometric point")."""
    c, sn = s * math.cos(theta), s * math.sin(theta)
    return np.array([[c, -sn, -0.5 * (c - sn)], [sn, c, -0.5 * (sn + c)], [0.0, 0.0, 1.0]])


def _rect(pixels: list, s: float, theta: float) -> tuple[int, int, int, int]:
    """The lixels (i0, j0, i1, j1), i1 and j1 excluded, whose cells cover the pixels."""
    (a, b, e), (c, d, f), _ = lixel_of_pixel(s, theta).tolist()
    xs = [a * x + b * y + e for x, y in pixels]
    ys = [c * x + d * y + f for x, y in pixels]
    i0, j0 = math.floor(min(xs) + 0.5), math.floor(min(ys) + 0.5)
    return i0, j0, math.floor(max(xs) + 0.5) + 1, math.floor(max(ys) + 0.5) + 1


def _texels(rect) -> int:
    return (rect[2] - rect[0]) * (rect[3] - rect[1])


def _rects(jobs: list[PlaneMap], s: float) -> list[tuple[int, int, int, int]]:
    """Each plane map's texel rectangle at s lixels per pixel (and its twist)."""
    return [_rect(j.pixels, s, j.twist) for j in jobs]


def _choose_twists(jobs: list[PlaneMap], always: bool) -> None:
    """Each map's twist (§2): the tightest rectangle's rotation, kept when ``always``
    or when it saves at least 1 - TWIST_GAIN."""
    for j in jobs:
        p = np.array(j.pixels)
        t = min_area_twist(p)
        if always or np.prod(np.ptp(p @ rotation2d(t).T, axis=0)) < TWIST_GAIN * np.prod(np.ptp(p, axis=0)):
            j.twist = t


def _fraction_of_a_lixel(jobs: list[PlaneMap], budget: float) -> float:
    """The largest s <= 1 (to 0.1 %) whose rectangles take at most ``budget`` texels, none wider than MAX_MAP_SIDE."""
    s = 1.0
    for _ in range(60):
        rects = _rects(jobs, s)
        total = sum(map(_texels, rects))
        side = max(max(r[2] - r[0], r[3] - r[1]) for r in rects)
        if total <= budget and side <= MAX_MAP_SIDE:
            return s
        shrink = min(math.sqrt(budget / total), MAX_MAP_SIDE / side)
        s *= min(shrink, 1.0) * (1 - 1e-3) if shrink < 1 - 1e-3 else (1 - 1e-3)
    raise WarpError(f"the plane maps do not fit a budget of {budget:.3g} texels: raise the map size or plane budget")


def light_map(job: PlaneMap, s: float, origin: np.ndarray, tol: float, options: WarpOptions) -> ShadowMap:
    """Plane k's matrix in world coordinates: viewer pixel -> lixel -> texel -> NDC,
    depth z = a·w - b·h fitted to the clip volume's points."""
    i0, j0, i1, j1 = job.rect
    wm, hm = i1 - i0, j1 - j0
    to_texel = np.array([[1.0, 0.0, 0.5 - i0], [0.0, 1.0, 0.5 - j0], [0.0, 0.0, 1.0]])   # lixel (i0, j0) -> (½, ½)
    to_ndc = np.array([[2.0 / wm, 0.0, -1.0], [0.0, 2.0 / hm, -1.0], [0.0, 0.0, 1.0]])
    x_row, y_row, w_row = to_ndc @ to_texel @ lixel_of_pixel(s, job.twist) @ job.pixel @ job.rows
    # Depth: the fit points' z / w = -h / w (w > 0 on them) onto [-1, 1], as the unit-cube fit pads it.
    zlo, zhi = job.depth
    win = window_matrix([-1.0, -1.0, zlo], [1.0, 1.0, zhi])
    z_row = win[2, 3] * w_row - win[2, 2] * job.height
    world = np.array([x_row, y_row, z_row, w_row]) @ translation(-origin)
    # Linear depth (Scherzer §4.2): 1 at the fit points' lowest height (farthest from the light), -1 at the highest.
    depth_row = fitted_row(-job.height, job.fit_h[:, :3]) @ translation(-origin) if options.linear_z else None
    region = Region(job.plane.normal.copy(), float(job.plane.offset), job.polygon + origin, tol)
    return ShadowMap(world, (wm, hm), "LESS", f"plane:{job.index}", region=region, depth_row=depth_row)


def _fallback_size(texels: float, options: WarpOptions) -> tuple[int, int]:
    """A fallback map of at most ``texels`` texels, shaped like ``shadow_map_size``."""
    f = math.sqrt(texels / (options.shadow_map_size[0] * options.shadow_map_size[1]))
    return (max(1, int(options.shadow_map_size[0] * f)), max(1, int(options.shadow_map_size[1] * f)))
