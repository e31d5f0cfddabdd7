"""Plane-optimal shadow maps: Chong & Gortler, "A Lixel for every Pixel" (EGSR 2004).

One map per plane of interest, exact on that plane, plus a conventional
fallback map (§3):

* **The matrix** (§2, Eq. 1, 7-10; :func:`addon.warp.plane_map.plane_light_matrix`):
  five point constraints, solved by SVD with rank and residual checks. On the
  plane, a point's light-image x, y equal its viewer-image x, y.
* **Sign** (Fig. 5): the matrix is scaled (and its sign chosen) so that w > 0
  and w equals the viewer's clip w on the plane's needed part; every caster
  between the light and that part then has w > 0 too.
* **Depth**: the z row is free (§2 footnote). Lixel uses
  z_clip = a·w - b·h(x), h = the height above the plane on the light's side,
  so depth grows away from the light along every light ray, the plane itself
  has one constant depth, and a, b fit the needed points into [-1, 1] (the
  unit-cube fit's padding). With ``WarpOptions.linear_z`` the stored depth is
  the linear height (``ShadowMap.depth_row``, Scherzer §4.2).
* **Less of the plane** (§2, Fig. 6): the needed rays C are those through
  P ∩ R, with R = V ∩ S_r ∩ L the body's visible part (between near and far,
  in front of the camera, inside the spot cone and the receivers' bounds),
  limited to the plane's extent polygon if it has one. Their light image is
  bounded by a rectangle of whole lixels; its lower-left lixel is renumbered
  (0, 0). The point of the plane under pixel coordinates p (pixel (i, j)'s
  centre at (i + ½, j + ½)) lands on lixel s·R(θ)·(p - ½) - (i0, j0), whose
  centre is sampled at texel coordinate + ½. At one lixel per pixel (s = 1,
  no twist) the map is the identity up to the renumbering: every pixel centre
  is a lixel centre, so the lixel samples exactly the pixel's point, and the
  shading pass reads that one lixel unfiltered (``gpu_shaders/shade_frag.glsl``:
  the shadow on the plane is then the ray-cast one; a PCF kernel would only
  blur it over k pixels). When the budget holds fewer lixels than pixels, a
  uniform 2D scale s < 1 is included, the same for every plane, and
  optionally a twist (a 2D rotation, ``WarpOptions.plane_twist``) that shrinks
  the rectangle.
* **Regions and order** (§3): map k serves ``Region`` (the plane, the needed
  polygon, a tolerance): points within the tolerance of the plane whose
  projection falls in the polygon. Plane maps come first in plane order, the
  fallback last, so ``ShadowSetup.map_index`` uses the plane map on the plane
  and the fallback everywhere else. A plane map's clip volume holds its whole
  region and every point of B between the light and the region (its casters).
* **Fallback**: the uniform method's frame maps (``frame_map``) over the hull
  of B minus the plane regions. The regions are slabs of width 2·tolerance, so
  that hull is B itself: the fallback covers every point of B.
* **Budget** (§3: each map gets a fixed number of lixels): T =
  shadow_map_size texels. Plane maps together take at most ``plane_budget``·T
  and only what one lixel per pixel needs (more would sample the same points
  again); every fallback map gets the rest (T minus the plane maps' texels;
  the per-map convention of ``uniform.map_sizes``), so a larger T refines the
  fallback. Reported in ``diagnostics.extra["budget"]``.
* **Planes**: ``WarpOptions.planes`` ((point, normal) or (point, normal,
  extent polygon)); without any, the top face of the widest flat receiver box
  (``plane_map.default_plane``).

A plane that cannot have a map (seen edge-on, not in view, the light in its
plane, a failed solve) is left out with a recorded fallback; the fallback map
then serves it.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..body import IntersectionBody
from ..fit import fit_runs, window_matrix
from ..frame import body_light_angles, light_frames
from ..geometry import point_runs, translation
from ..linear_depth import frame_depth_row
from ..plane_map import (FLAT_RATIO, PlaneOfInterest, clip_to_polygon, convex_polygon_on_plane,
                         default_plane_of, enclosing_polygon, flattest_box, is_convex_polygon, min_area_twist, offset_steps,
                         VIEW_CORNER_RAYS, plane_light_matrix, plane_section, polygon_area,
                         rotation2d)
from ..polyhedron import ConvexPolytope
from ..diagnostics import Diagnostics
from ..types import Light, Region, ShadowMap, ShadowSetup, View, WarpError, WarpOptions
from .common import NEAR_PLANE_NOTE, frame_maps

MAX_SIDE = 16384
MAX_REGION_VERTICES = 32
"""A region polygon has at most this many vertices (the shader's limit,
``addon.gpu.shaders.MAX_POLYGON``); a larger one is replaced by an enclosing one."""
MAX_MAPS = 8
"""Maps one shading pass can select from (``addon.gpu.shaders.MAX_MAPS``): plane
maps beyond what this leaves next to the fallback maps are left out, smallest first."""
REGION_TOLERANCE = 1e-6
"""A point belongs to a plane's region within this fraction of the scene scale
(at least 100x the body tolerance)."""
NEAR_FRACTION = 1e-6
"""A point light inside B: casters nearer than this fraction of the scene scale
to the light's height are left out of a plane map (as ``frame.perspective_frame``)."""
TWIST_GAIN = 0.99
"""plane_twist='auto' twists when the rotated rectangle is below this fraction
of the unrotated one and the budget forces fewer lixels than pixels."""


@dataclasses.dataclass
class _PlaneJob:
    """One plane's map while the budget is shared out (coordinates relative to the camera)."""

    index: int
    plane: PlaneOfInterest
    polygon: np.ndarray          # the needed polygon on P
    rows: np.ndarray             # 3x4: x, y, w rows; on P they equal the viewer's clip x, y, w
    pixel: list                  # 3x3: viewer clip (x, y, w) -> pixel (px, py, 1)
    height: np.ndarray           # 4-vector: height above P on the light's side, h(x) = height · (x, 1)
    fit_h: np.ndarray            # (N, 4) region slab + casters, homogeneous: all inside the map's clip volume
    depth: tuple                 # the least and greatest -h / w over fit_h (the map's z / w before its window)
    heights: tuple               # the least and greatest h over fit_h
    pixels: list                 # (x, y) pixel coordinates of the tolerance-grown polygon
    info: dict
    twist: float = 0.0
    rect: tuple = (0, 0, 1, 1)   # (i0, j0, i1, j1) in texels of the scaled, twisted image


def _corner_ray_points(view: View, origin: list, nx: float, ny: float, nz: float, off: float) -> list:
    """p^1..p^4: where the rays through the view's corners meet P (n . x = off,
    relative to ``origin``), homogeneous: ``line_plane_points`` of the view
    frustum's near and far corners on those rays (``VIEW_CORNER_RAYS``), in floats."""
    ox, oy, oz = origin
    corners = view.corners().tolist()
    points = []
    for i, j in zip(*VIEW_CORNER_RAYS):
        (ax, ay, az), (bx, by, bz) = corners[i], corners[j]
        ax, ay, az, bx, by, bz = ax - ox, ay - oy, az - oz, bx - ox, by - oy, bz - oz
        pa, pb = nx * ax + ny * ay + nz * az - off, nx * bx + ny * by + nz * bz - off
        points.append([pb * ax - pa * bx, pb * ay - pa * by, pb * az - pa * bz, pb - pa])
    return points


def _view_w(view: View, x: float, y: float, z: float) -> float:
    """The viewer's clip w (``view.world_to_clip`` row 3) of the point (x, y, z)
    relative to the camera."""
    wx, wy, wz, w0 = view.world_to_clip[3].tolist()
    ox, oy, oz = view.position.tolist()
    return wx * (x + ox) + wy * (y + oy) + wz * (z + oz) + w0


def _planes_of(options: WarpOptions, body: IntersectionBody, diag: Diagnostics) -> list[PlaneOfInterest]:
    if options.planes:
        return [PlaneOfInterest.from_option(p, i) for i, p in enumerate(options.planes)]
    plane = default_plane_of(body.culled.receivers)
    if plane is None:
        diag.fallback("planes", _no_default_plane(body.culled.receivers.boxes))
        return []
    diag.extra["default_plane"] = plane.name
    return [plane]


def _no_default_plane(receiver_boxes) -> str:
    """Why no receiver gives a default plane, and what plane_optimal does then."""
    flattest = flattest_box(receiver_boxes)
    if flattest is None:
        found = "no receiver box is in view"
    else:
        i, height, side = flattest
        found = (f"no receiver in view is flat (a plane of interest needs a box at most {FLAT_RATIO:.0%} as high as "
                 f"its smaller side; the flattest, receiver box {i}, is {height:.3g} high over {side:.3g}, "
                 f"{height / side:.0%}): the receivers are not planar, e.g. a terrain")
    return (f"no plane of interest given and {found}. plane_optimal renders with its fallback map alone, the "
            f"uniform map with the whole texel budget (Chong-Gortler §5: where no plane describes the receivers "
            f"the method has nothing to be exact on); give planes (Planes of Interest in the Lixel panel, or "
            f"\"planes\" in the config) to add plane maps")


def _prepare(k: int, plane: PlaneOfInterest, view: View, light: Light, body: IntersectionBody,
             origin: np.ndarray, tol: float, diag: Diagnostics) -> _PlaneJob | None:
    """Everything about plane k except its rectangle; None (with a recorded
    fallback) when the plane cannot have a map."""
    role = f"plane:{k}"
    n = plane.normal
    nx, ny, nz = n.tolist()
    ox, oy, oz = origin.tolist()
    off = plane.offset - (nx * ox + ny * oy + nz * oz)    # plane offset, relative coordinates
    l_h = light.homogeneous_from(origin)
    lx, ly, lz, lw = l_h
    scale = body.scale
    # The light's side of the plane: h(x) = height above P towards the light.
    light_side = nx * lx + ny * ly + nz * lz - off * lw
    if abs(light_side) <= (1e-9 if lw == 0 else max(tol, 1e-9 * scale)):
        what = "the sun shines along" if lw == 0 else "the light lies in"
        diag.fallback(role, f"{what} {plane.name}: every light ray reaching it grazes it, so no plane map "
                            f"exists; the fallback map serves it")
        return None
    side = 1.0 if light_side > 0 else -1.0
    height = np.array([side * nx, side * ny, side * nz, -side * off])      # h(X) = height · (x, 1)
    # The camera on the plane: it is seen edge-on and covers no pixel.
    if view.orthographic:                                           # the centre of projection is a direction
        dx, dy, dz = view.direction.tolist()
        edge_on = abs(nx * dx + ny * dy + nz * dz) <= 1e-9
    else:
        ex, ey, ez = view.position.tolist()
        edge_on = abs(nx * (ex - ox) + ny * (ey - oy) + nz * (ez - oz) - off) <= max(tol, 1e-9 * scale)
    if edge_on:
        diag.fallback(role, f"{plane.name} passes through the camera (seen edge-on): it covers no pixel")
        return None
    # Less of the plane: P ∩ R (R = V ∩ S_r ∩ L), within the plane's extent.
    region = body.visible_polytope
    shift = (body.origin - origin).tolist()                         # (B's frame to ours: none when both are the camera's)
    poly = plane_section(region.vertices, n, off - sum(a * b for a, b in zip(n.tolist(), shift)), body.tolerance,
                         region.loops)
    if poly is not None and any(shift):
        poly += shift
    if poly is not None and plane.extent is not None:
        ext = [(x - ox, y - oy, z - oz) for x, y, z in np.asarray(plane.extent, dtype=np.float64).tolist()]
        if not is_convex_polygon(ext, n, body.tolerance):       # (a box's top, a hull: already their own hull)
            ext = convex_polygon_on_plane(ext, n, body.tolerance)
        poly = None if ext is None else clip_to_polygon(poly, ext, n, body.tolerance)
    if poly is not None and len(poly) > MAX_REGION_VERTICES:
        poly = enclosing_polygon(poly, n, MAX_REGION_VERTICES)
    vertices = None if poly is None else poly.tolist()
    if vertices is None or polygon_area(vertices, n) <= (tol * tol):
        diag.fallback(role, f"{plane.name} has no visible part (behind the camera, outside the view, the spot "
                            f"cone or the receivers' bounds)")
        return None
    # p^1..p^4: where the rays through the view's corners meet P (near and far corners of V, relative).
    p = _corner_ray_points(view, [ox, oy, oz], nx, ny, nz, off)
    try:
        m, info = plane_light_matrix(p, l_h, scale)
    except WarpError as exc:
        diag.fallback(role, f"{plane.name}: {exc}")
        return None
    # Sign (Fig. 5) and scale: w equal to the viewer's clip w on the plane.
    cx, cy, cz = (sum(c) / len(vertices) for c in zip(*vertices))
    w_view = _view_w(view, cx, cy, cz)
    wx, wy, wz, w0 = m[3].tolist()
    w_light = wx * cx + wy * cy + wz * cz + w0
    if not (w_view > 0 and abs(w_light) > 0):
        diag.fallback(role, f"{plane.name}: the needed part is not in front of the camera")
        return None
    rows = m[[0, 1, 3]] * (w_view / w_light)
    # The region (what Region.contains accepts) and its casters in B.
    outwards = offset_steps(vertices, n)
    grown = [(x + tol * dx, y + tol * dy, z + tol * dz) for (x, y, z), (dx, dy, dz) in zip(vertices, outwards)]
    casters, near_clamped = _casters(vertices, outwards, grown, n, height, l_h, tol, body, origin)
    if near_clamped:
        diag.fallback(f"{role}: near plane", "the light is inside B; casters nearer than 1e-6 of the scene scale "
                                             "to the light's height are not in the plane map")
    # The points the map's clip volume holds: the region's slab (tol below and above P) and the casters.
    tx, ty, tz = tol * nx, tol * ny, tol * nz
    slab = [(x - tx, y - ty, z - tz) for x, y, z in grown] + [(x + tx, y + ty, z + tz) for x, y, z in grown]
    fit_h = np.ones((len(slab) + len(casters), 4))
    fit_h[:len(slab), :3] = slab
    fit_h[len(slab):, :3] = casters
    # Their heights h and clip w (the map's z row is -height before its window, its w row rows[2]).
    h, w = np.array([height, rows[2]]) @ fit_h.T
    if not (w > 0).all():
        diag.fallback(role, "some casters are behind the plane map's centre of projection and were left out")
        ahead = w > 0
        fit_h, h, w = fit_h[ahead], h[ahead], w[ahead]
    h_over_w = h / w
    depth = (-float(h_over_w.max()), -float(h_over_w.min()))
    heights = (float(h.min()), float(h.max()))
    rx, ry = view.resolution[0] / 2, view.resolution[1] / 2
    pixel = [[rx, 0.0, rx], [0.0, ry, ry], [0.0, 0.0, 1.0]]
    r0, r1, r2 = rows.tolist()
    ax, ay, az, a0 = (rx * a + rx * c for a, c in zip(r0, r2))        # pixel @ rows, in floats
    bx, by, bz, b0 = (ry * b + ry * c for b, c in zip(r1, r2))
    wx, wy, wz, w0 = r2
    pixels = []                                       # the grown polygon's pixel coordinates
    for x, y, z in grown:
        pw = wx * x + wy * y + wz * z + w0
        pixels.append(((ax * x + ay * y + az * z + a0) / pw, (bx * x + by * y + bz * z + b0) / pw))
    area = _area2d(pixels)
    if area < 1.0:
        diag.fallback(role, f"{plane.name} covers less than one pixel of the view ({area:.3g})")
        return None
    info = dict(info, pixel_area=float(area), near_clamped=near_clamped)
    return _PlaneJob(k, plane, poly, rows, pixel, height, fit_h, depth, heights, pixels, info)


def _casters(poly: list, outwards: list, grown: list, n, height, l_h, tol, body, origin):
    """Vertices of B ∩ C: B's points on the needed rays C (the light rays through
    the region, §2 Fig. 5-6) from the light down to just beyond the plane.

    C is the cone (a prism for a sun) from the light over the region polygon
    ``grown`` (``poly`` moved out by tol along ``outwards``), grown by
    tol·(1 + tan α) so that the slab points of the region (whose light rays
    meet P up to tol·tan α away, α = the light's incidence) are on it, and cut
    at h = -tol. For a point light inside B the part within NEAR_FRACTION of
    the scene scale below the light's height is cut off (returned flag)."""
    h = height.tolist()
    hx, hy, hz, h0 = h
    lx, ly, lz, lw = l_h
    nx, ny, nz = n.tolist()
    tan = 0.0                                             # tan α: the steepest light ray over the region
    for gx, gy, gz in grown:
        rx, ry, rz = (-lx, -ly, -lz) if lw == 0 else (gx - lx / lw, gy - ly / lw, gz - lz / lw)
        along = abs(rx * nx + ry * ny + rz * nz)                                # |ray| cos α
        across = math.sqrt(max(rx * rx + ry * ry + rz * rz - along * along, 0.0))  # |ray| sin α
        tan = max(tan, across / max(along, 1e-300))
    grow = tol * (2 + min(tan, 1e12))
    corners = [(x + grow * dx, y + grow * dy, z + grow * dz) for (x, y, z), (dx, dy, dz) in zip(poly, outwards)]
    normals, offsets = _cone_facets(corners, h, l_h, tol)
    b_poly = _polytope(body, origin)
    if b_poly is not None and len(normals) == len(corners) + 1:          # (every side plane made)
        points = _cone_section(b_poly, normals, offsets, *_cone_edges(corners, h, l_h, tol))
    else:
        points = _clip_body(body, origin, np.array(normals), np.array(offsets))
    if points is None:
        return np.zeros((0, 3)), False
    near_clamped = False
    if lw != 0:
        top = (hx * lx + hy * ly + hz * lz + h0 * lw) / lw - NEAR_FRACTION * body.scale
        if float((points @ height[:3]).max()) + h0 > top:
            near_clamped = True
            points = _clip_body(body, origin, np.array(normals + [h[:3]]), np.array(offsets + [top - h0]))
            if points is None:
                return np.zeros((0, 3)), near_clamped
    return points, near_clamped


def _cone_facets(corners: list, height: list, l_h, tol: float) -> tuple[list, list]:
    """C's facets (see ``_casters``) as unit normals and offsets (normal . x <=
    offset inside): h(x) >= -tol (h(x) = ``height`` . (x, 1)), then the side
    planes through each edge (a, b) of ``corners`` and the light, facing away
    from the corners' centre (an edge pointing at the light spans no plane and
    has none)."""
    hx, hy, hz, h0 = height
    lx, ly, lz, lw = l_h
    cx, cy, cz = (sum(c) / len(corners) for c in zip(*corners))
    normals, offsets = [(-hx, -hy, -hz)], [tol + h0]
    for (ax, ay, az), (bx, by, bz) in zip(corners, corners[1:] + corners[:1]):
        ex, ey, ez = bx - ax, by - ay, bz - az
        tx, ty, tz = lx - ax * lw, ly - ay * lw, lz - az * lw     # from a towards the light (homogeneous)
        sx, sy, sz = ey * tz - ez * ty, ez * tx - ex * tz, ex * ty - ey * tx
        length = math.sqrt(sx * sx + sy * sy + sz * sz)
        if length == 0:
            continue
        sx, sy, sz = sx / length, sy / length, sz / length
        offset = sx * ax + sy * ay + sz * az
        if sx * cx + sy * cy + sz * cz > offset:
            sx, sy, sz, offset = -sx, -sy, -sz, -offset
        normals.append((sx, sy, sz))
        offsets.append(offset)
    return normals, offsets


def _cone_edges(corners: list, height: list, l_h, tol: float) -> tuple[list, list, list]:
    """The edges of C (see ``_casters``) as (starts, steps, ends): edge i is
    starts[i] + t·steps[i] for 0 <= t <= ends[i]. C's base corners q_i are
    where the light's rays through ``corners`` (on P: h = 0) reach h = -tol;
    from each, one edge runs up to the light (t <= 1; a sun's has no end) and
    one to the next base corner."""
    hx, hy, hz, h0 = height
    lx, ly, lz, lw = l_h
    rise = hx * lx + hy * ly + hz * lz             # height . l_h = rise + h0·lw: the light's (homogeneous) height
    if lw == 0:                     # towards the sun along (lx, ly, lz): h rises by ``rise`` per unit
        k = tol / rise
        base = [(x - k * lx, y - k * ly, z - k * lz) for x, y, z in corners]
        up = [(lx, ly, lz)] * len(base)
        up_ends = [math.inf] * len(base)
    else:                           # q = c + (tol / H)(c - light), H the light's height (c on P: h(c) = 0)
        px, py, pz = lx / lw, ly / lw, lz / lw
        k = tol / (rise / lw + h0)
        base = [(x + k * (x - px), y + k * (y - py), z + k * (z - pz)) for x, y, z in corners]
        up = [(px - x, py - y, pz - z) for x, y, z in base]
        up_ends = [1.0] * len(base)
    along = [(bx - ax, by - ay, bz - az) for (ax, ay, az), (bx, by, bz) in zip(base, base[1:] + base[:1])]
    return base + base, up + along, up_ends + [1.0] * len(base)


def _cone_section(poly: ConvexPolytope, normals: list, offsets: list, starts: list, steps: list,
                  ends: list) -> np.ndarray | None:
    """Points whose convex hull is poly ∩ C, for a convex C given both by its
    facets (``normals`` @ x <= ``offsets``, unit normals) and by its edges
    (starts[i] + t·steps[i], 0 <= t <= ends[i]), or None when nothing of poly
    is in C. ``poly.section`` by C's facets gives the same points, but finds
    C's edges among every pair of its facets.

    A vertex of poly ∩ C lies on three of their facets, so on an edge of poly
    (two or three of poly's) or on an edge of C (two or three of C's), and it
    is an end of that edge's stretch inside poly ∩ C, since a vertex is not
    inside any segment of poly ∩ C. So the ends of poly's edges clipped to C
    and of C's edges clipped to poly are the points (Cyrus-Beck: t·rate <=
    room for each facet), found in one clip of all the edges by all the
    facets in which an edge's own polytope gives it no bound (room = +inf: an
    edge lies in its own polytope, which rounding could contradict)."""
    a, b = poly.vertices[poly.edges().T]
    seg_start = np.concatenate([a, starts])
    seg_step = np.concatenate([b - a, steps])
    planes = np.concatenate([normals, poly.normals])
    limits = np.concatenate([offsets, poly.offsets])
    # (facets, edges); + 0.0 turns -0.0 into +0.0: an edge parallel to a facet reads as rising, and
    # room / +0 is +inf (no bound) inside, -inf (nothing left) outside, NaN (ignored by fmin) on it.
    rate = planes @ seg_step.T + 0.0
    room = limits[:, None] - planes @ seg_start.T
    c_facets, poly_edges = len(normals), len(a)
    room[:c_facets, poly_edges:] = np.inf
    room[c_facets:, :poly_edges] = np.inf
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):      # (a huge ratio is no bound either)
        ratio = room / rate
    rising = rate >= 0
    t_hi = np.minimum(np.fmin.reduce(np.where(rising, ratio, np.inf), axis=0),
                      np.concatenate([np.ones(poly_edges), ends]))
    t_lo = np.maximum(np.fmax.reduce(np.where(rising, -np.inf, ratio), axis=0), 0.0)
    hit = t_lo <= t_hi
    if not hit.any():
        return None
    start, step = seg_start[hit], seg_step[hit]
    return np.concatenate([start + t_lo[hit, None] * step, start + t_hi[hit, None] * step])


def _polytope(body: IntersectionBody, origin: np.ndarray) -> ConvexPolytope:
    """B's polytope relative to ``origin``."""
    return body.polytope_from(origin)


def _clip_body(body: IntersectionBody, origin: np.ndarray, normals: np.ndarray,
               offsets: np.ndarray) -> np.ndarray | None:
    """Points (relative to ``origin``) whose convex hull is B ∩ {normals @ x <= offsets}
    (its vertices among them), or None if empty."""
    return body.polytope_from(origin).section(normals, offsets)


def _area2d(p: list) -> float:
    """The area of a polygon given as (x, y) pairs (the shoelace formula)."""
    return 0.5 * abs(sum(ax * by - ay * bx for (ax, ay), (bx, by) in zip(p, p[1:] + p[:1])))


def _rect(pixels: list, s: float, theta: float) -> tuple[int, int, int, int]:
    """The lixels (i0, j0, i1, j1), i1 and j1 excluded, whose cells cover the
    pixels (x, y) mapped onto the lixel lattice by ``_lixel_of_pixel``: lixel
    (i, j) has its centre at lattice point (i, j) and its cell within ½ of it."""
    (a, b, e), (c, d, f) = _lixel_of_pixel(s, theta)
    xs = [a * x + b * y + e for x, y in pixels]
    ys = [c * x + d * y + f for x, y in pixels]
    i0, j0 = math.floor(min(xs) + 0.5), math.floor(min(ys) + 0.5)
    return i0, j0, math.floor(max(xs) + 0.5) + 1, math.floor(max(ys) + 0.5) + 1


def _lixel_of_pixel(s: float, theta: float) -> list:
    """The pixel -> lixel lattice map ℓ = s·R(θ)·(p - ½) (the first two rows
    of its 3x3 matrix). Pixel (i, j) covers [i, i + 1] x [j, j + 1] (its centre
    at p = (i + ½, j + ½), as the viewer's pixel map puts it), so at s = 1 and
    no twist every pixel centre lands on the lattice point (i, j): the centre
    of a lixel, which then samples exactly the pixel's point of the plane (§2:
    "exactly one lixel ... samples the exact same geometric point")."""
    c, sn = s * math.cos(theta), s * math.sin(theta)
    return [[c, -sn, -0.5 * (c - sn)], [sn, c, -0.5 * (sn + c)]]


def _texels(rect) -> int:
    return (rect[2] - rect[0]) * (rect[3] - rect[1])


def _rects(jobs: list[_PlaneJob], s: float) -> list[tuple[int, int, int, int]]:
    """Each plane map's texel rectangle at s lixels per pixel (and its twist)."""
    return [_rect(j.pixels, s, j.twist) for j in jobs]


def _fits(rects: list, budget: float) -> bool:
    """Whether the rectangles take at most ``budget`` texels, none wider than MAX_SIDE."""
    return sum(map(_texels, rects)) <= budget and max(max(r[2] - r[0], r[3] - r[1]) for r in rects) <= MAX_SIDE


def _share_budget(jobs: list[_PlaneJob], budget: float, twist_mode: str) -> float:
    """The common lixels-per-pixel scale s of the plane maps, and each map's
    twist and rectangle, within ``budget`` texels: one lixel per pixel (the
    paper's exact sampling, §2) when it fits, else the largest s < 1 that does
    (the lixels then appear as squares of 1/s pixels, §2), with the twist when
    it makes the rectangles smaller (``plane_twist``)."""
    if not jobs:
        return 1.0
    for j in jobs:
        j.twist = 0.0
    need = sum(map(_texels, _rects(jobs, 1.0)))
    if twist_mode == "on" or (twist_mode == "auto" and need > budget):
        _choose_twists(jobs, always=twist_mode == "on")
    s = 1.0 if _fits(_rects(jobs, 1.0), budget) else _fraction_of_a_lixel(jobs, budget)
    for j, r in zip(jobs, _rects(jobs, s)):
        j.rect = r
    return s


def _choose_twists(jobs: list[_PlaneJob], always: bool) -> None:
    """Each map's twist (§2): the rotation giving the tightest rectangle around
    its pixels, kept when ``always`` or when it saves at least 1 - TWIST_GAIN."""
    for j in jobs:
        p = np.array(j.pixels)
        t = min_area_twist(p)
        if always or np.prod(np.ptp(p @ rotation2d(t).T, axis=0)) < TWIST_GAIN * np.prod(np.ptp(p, axis=0)):
            j.twist = t


def _fraction_of_a_lixel(jobs: list[_PlaneJob], budget: float) -> float:
    """The largest s <= 1 (to 0.1 %) whose rectangles fit ``budget`` texels and MAX_SIDE."""
    s = 1.0
    for _ in range(60):
        rects = _rects(jobs, s)
        if _fits(rects, budget):
            return s
        total = sum(map(_texels, rects))
        side = max(max(r[2] - r[0], r[3] - r[1]) for r in rects)
        shrink = min(math.sqrt(budget / total), MAX_SIDE / side)
        s *= min(shrink, 1.0) * (1 - 1e-3) if shrink < 1 - 1e-3 else (1 - 1e-3)
    raise WarpError("plane_optimal: could not fit the plane maps into the texel budget")


def _plane_map(job: _PlaneJob, s: float, origin: np.ndarray, tol: float, options: WarpOptions) -> ShadowMap:
    i0, j0, i1, j1 = job.rect
    wm, hm = i1 - i0, j1 - j0
    to_texel = [[1.0, 0.0, 0.5 - i0], [0.0, 1.0, 0.5 - j0]]         # lixel (i0, j0)'s centre to texel (½, ½)
    to_ndc = [[2.0 / wm, 0.0, -1.0], [0.0, 2.0 / hm, -1.0]]
    pixel_to_ndc = _affine_then(to_ndc, _affine_then(to_texel, _lixel_of_pixel(s, job.twist)))
    (ax, ay, a0), (bx, by, b0) = _affine_then(pixel_to_ndc, job.pixel)
    x_row, y_row, w_row = job.rows.tolist()                  # on P: the viewer's clip x, y, w
    x_row, y_row = ([ax * x + ay * y + a0 * w for x, y, w in zip(x_row, y_row, w_row)],
                    [bx * x + by * y + b0 * w for x, y, w in zip(x_row, y_row, w_row)])
    # Depth: the fit points' z / w = -h / w (w > 0 on them) onto [-1, 1], as the unit-cube fit pads it.
    (zlo, zhi), (hlo, hhi) = job.depth, job.heights
    win = window_matrix([-1.0, -1.0, zlo], [1.0, 1.0, zhi]).tolist()
    height = job.height
    z_row = [win[2][3] * w - win[2][2] * h for h, w in zip(height.tolist(), w_row)]
    ox, oy, oz = origin.tolist()
    world = np.array([[x, y, z, t - (x * ox + y * oy + z * oz)]                 # m @ translation(-origin)
                      for x, y, z, t in (x_row, y_row, z_row, w_row)])
    depth_row = None
    if options.linear_z:
        span = max(hhi - hlo, tol)
        pad = 1e-7 * span
        # z = 1 at the lowest height (farthest from the light), -1 at the highest
        k = 2.0 / (span + 2 * pad)
        depth_row = (-k * height + np.array([0, 0, 0, 1.0 + k * (hlo - pad)])) @ translation(-origin)
    n = job.plane.normal
    region = Region(n.copy(), float(job.plane.offset), job.polygon + origin, tol)
    return ShadowMap(world, (wm, hm), "LESS", f"plane:{job.index}", region=region, depth_row=depth_row)


def _affine_then(outer: list, inner: list) -> list:
    """The 2D affine map ``outer`` after ``inner``, each given by the first two
    rows of its 3x3 matrix (the last is (0, 0, 1)), in floats."""
    (a, b, c), (d, e, f) = outer
    (p, q, r), (s, t, u) = inner[0], inner[1]
    return [[a * p + b * s, a * q + b * t, a * r + b * u + c], [d * p + e * s, d * q + e * t, d * r + e * u + f]]


def _fallback_size(texels: float, options: WarpOptions) -> tuple[int, int]:
    """A fallback map of at most ``texels`` texels, shaped like ``shadow_map_size``."""
    f = math.sqrt(texels / (options.shadow_map_size[0] * options.shadow_map_size[1]))
    return (max(1, int(options.shadow_map_size[0] * f)), max(1, int(options.shadow_map_size[1] * f)))


def plane_optimal(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    theta, gamma = body_light_angles(view, light, body)
    diag = Diagnostics("plane_optimal", theta, gamma, body_vertices=body.vertices)
    origin = view.position
    tol = max(REGION_TOLERANCE * body.scale, 100 * body.tolerance)
    planes = _planes_of(options, body, diag)
    jobs = [j for j in (_prepare(k, p, view, light, body, origin, tol, diag) for k, p in enumerate(planes))
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
    plane_budget = options.plane_budget * total
    s = _share_budget(jobs, plane_budget, options.plane_twist)
    maps = [_plane_map(j, s, origin, tol, options) for j in jobs]
    used = sum(m.size[0] * m.size[1] for m in maps)
    remaining = max(total - used, 1)
    size = _fallback_size(remaining, options)
    if len(frames) > 1:                    # a point light's cube faces: fitted all at once (as uniform does)
        fitted = fit_runs(np.array([f.to_light for f in frames]), *point_runs([f.points for f in frames]))
        maps += [ShadowMap(m, size, "LESS", f"fallback:{f.role}") for m, f in zip(fitted, frames)]
    else:
        fm = frame_maps(frames, size, options.texel_snapping)[0]
        fm.role = "fallback"
        maps.append(fm)
    if options.linear_z:                   # the fallback maps' linear depth (Scherzer §4.2), as uniform's
        for m, fr in zip(maps[len(jobs):], frames):
            m.depth_row = frame_depth_row(fr)
    for fr in frames:
        if fr.near_clamped:
            role = "fallback" if len(frames) == 1 else f"fallback:{fr.role}"
            diag.fallback(f"{role}: near plane", NEAR_PLANE_NOTE)
    fb_sizes = [list(size) for _ in frames]
    diag.extra["planes"] = [{
        "role": f"plane:{j.index}", "name": j.plane.name, "normal": j.plane.normal, "offset": j.plane.offset,
        "lixels_per_pixel": s, "twist_deg": math.degrees(j.twist), "rect": list(j.rect),
        "pixel_area": j.info["pixel_area"], "condition": j.info["condition"], "residual": j.info["residual"],
    } for j in jobs]
    diag.extra["budget"] = {
        "plane_budget": options.plane_budget, "total_texels": total, "plane_texels": used,
        "one_lixel_texels": sum(_texels(r) for r in _rects(jobs, 1.0)) if jobs else 0,
        "plane_share": used / total, "fallback_sizes": fb_sizes, "fallback_maps": len(frames),
        "lixels_per_pixel": s if jobs else None,
    }
    diag.extra["frames"] = [m.role for m in maps]
    return ShadowSetup(maps, diag)
