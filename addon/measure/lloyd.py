"""The physical limit of shadow-map sampling for a view (Lloyd's model): N_min and m_min.

Lloyd's storage factor: a shadow map with N texels, however it is warped, cannot
beat a maximum texel footprint (screen pixels per texel, linear) of

    m_min = sqrt(N_min / N)

where N_min is the fewest texels for which some parameterization gives every
visible point at least one texel per pixel in every direction:

    N_min = Rx·Ry / (4·tanθx·tanθy) · ∬ dA / z_min(q)²                      (1)

The integral runs over the view frustum projected along the light onto a plane
perpendicular to it; z_min(q) is the nearest eye depth of the frustum on the
light ray through q. ``Rx·Ry / (4·tanθx·tanθy·z²)`` is the camera's pixel density
(pixels per unit area) on a surface facing it at eye depth z (θx, θy are the
*half* fields of view), so (1) gives every light ray the texel density of its
most demanding point.

Which θ the closed forms mean (square frustum, θx = θy = θ gives the issue's text):

* light perpendicular to the view, in the view's vertical plane (camera up axis
  along the light): N_min = Rx·Ry·ln(f/n) / (2·tanθy). In general θ is the half
  field of view measured in the plane spanned by the view and light directions,
  the one the projection collapses. Derivation: the projection is the trapezoid
  |x| <= y·tanθx, n <= y <= f, z_min = y, so ∬ = 2·tanθx·ln(f/n).
* light parallel to the view: N_min = Rx·Ry·(1 + 2·ln(f/n)); the projection is the
  far rectangle, z_min = max(n, |x|/tanθx, |y|/tanθy), ∬ = 4·tanθx·tanθy·(1 + 2·ln(f/n)).

Exact evaluation (directional lights). Eye depth is affine along a light ray, so
its minimum over the (convex) segment inside the frustum lies at the segment's
entry point when the light travels with the view (l·v >= 0) and at its exit point
otherwise. The frustum faces the rays enter through (or leave through) tile the
projected region, and on each face the depth is an affine function of q, so (1)
is a sum over triangles of ∬ 1/L² for affine L, which has the closed form
(Hermite-Genocchi): ∬_T L⁻² dA = 2·|T| · g[L1, L2, L3] with g = -ln and g[...]
the second divided difference of g at the vertex values.

Point and spot lights. Rays are parameterized by solid angle: a pencil of rays of
solid angle dΩ has cross-section d²·dΩ at distance d from the light, so
N_min = K ∬ dΩ · max_ray (d/z)², the same formula with dA -> d²·dΩ (it reduces to
(1) for a distant light). (d/z) is monotonic along a ray, so its maximum is again
at the entry or exit face. On a plane at unit distance from the light, z/s =: A(q)
is affine in q on each face (s the ray parameter, p = L + s·(q - L)), and the
integrand is cos³α·(d/z)² = 1/(|q - L|·A(q)²): the face triangles are subdivided,
∬ 1/A² is exact on each and the mild 1/|q - L| is taken at the centroid.

Orthographic cameras have a constant pixel density, Rx·Ry / (width·height), so
N_min is that density times the projected area.

No bpy here: numpy only.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from ..warp.aliasing import pixel_density_constant  # noqa: F401 - K lives with the other formulas
from ..warp.geometry import normalize, perpendicular
from ..warp.polyhedron import hexahedron_faces
from ..warp.types import Light, View


def _neg_log_divided_difference(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """g[a, b, c] for g = -ln, elementwise, for positive values (stable when close).

    Uses sorted values x0 <= x1 <= x2 and g[x, y] = -log1p((y - x)/x)/(y - x)."""
    x = np.sort(np.stack([a, b, c], axis=-1), axis=-1)
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]

    def first(u, v):
        d = v - u
        small = d <= 1e-7 * u
        with np.errstate(divide="ignore", invalid="ignore"):
            exact = -np.log1p(d / u) / np.where(small, 1.0, d)
        # series: -1/u + d/(2u²) - d²/(3u³)
        series = -1.0 / u + d / (2 * u * u) - d * d / (3 * u ** 3)
        return np.where(small, series, exact)

    spread = x2 - x0
    close = spread <= 1e-4 * x0
    with np.errstate(divide="ignore", invalid="ignore"):
        exact = (first(x1, x2) - first(x0, x1)) / np.where(close, 1.0, spread)
    # g''/2 at the mean, plus the next term g''''/24·(Σ(x_i - m)² ...) is below 1e-8 relative here
    m = (x0 + x1 + x2) / 3.0
    series = 1.0 / (2.0 * m * m)
    return np.where(close, series, exact)


def integral_inverse_square_affine(tri_2d: np.ndarray, values: np.ndarray) -> np.ndarray:
    """∬_T 1/L(q)² dA over 2D triangles T (…, 3, 2) where L is affine with the
    positive vertex values ``values`` (…, 3). Exact (Hermite-Genocchi)."""
    t = np.asarray(tri_2d, dtype=np.float64)
    e1, e2 = t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :]
    area = 0.5 * np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0])
    v = np.asarray(values, dtype=np.float64)
    return 2.0 * area * _neg_log_divided_difference(v[..., 0], v[..., 1], v[..., 2])


def frustum_faces(view: View) -> list[np.ndarray]:
    """The six faces of the view frustum as world-space (4, 3) polygons."""
    return hexahedron_faces(view.corners())


def _outward_normals(faces: Sequence[np.ndarray]) -> list[np.ndarray]:
    centre = np.mean(np.concatenate(faces), axis=0)
    out = []
    for f in faces:
        n = np.zeros(3)
        for i in range(len(f)):  # Newell's method: robust for any planar polygon
            a, b = f[i], f[(i + 1) % len(f)]
            n += np.cross(a, b)
        norm = np.linalg.norm(n)
        if norm == 0:
            out.append(n)
            continue
        n /= norm
        if n @ (f.mean(axis=0) - centre) < 0:
            n = -n
        out.append(n)
    return out


def _fan(face: np.ndarray) -> np.ndarray:
    """(K-2, 3, 3) triangle fan of a convex polygon."""
    return np.stack([np.stack([face[0], face[i], face[i + 1]]) for i in range(1, len(face) - 1)])


def _subdivide(tris: np.ndarray, levels: int) -> np.ndarray:
    """Split each triangle (…, 3, D) into 4**levels congruent ones."""
    t = tris.reshape(-1, 3, tris.shape[-1])
    for _ in range(levels):
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        t = np.concatenate([np.stack(s, axis=1) for s in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return t


def n_min(view: View, light: Light, faces: Optional[Sequence[np.ndarray]] = None, *,
          quadrature_levels: int = 4) -> float:
    """Lloyd's N_min (texels) for ``view`` and ``light``, Eq. (1) of the module doc.

    ``faces``: the convex region to integrate over as outward polygons (default:
    the view frustum; pass e.g. the frustum clipped to the scene for a tighter
    limit). Directional lights are exact; point/spot lights subdivide each face
    triangle ``quadrature_levels`` times (4**levels pieces, error O(4**-levels)). Raises ValueError when the light lies inside or beside the region
    (a point light whose rays do not all leave one side of it)."""
    faces = list(frustum_faces(view) if faces is None else faces)
    normals = _outward_normals(faces)
    k = pixel_density_constant(view)
    w2c = view.world_to_camera

    def depth(points):
        p = np.asarray(points, dtype=np.float64)
        return -(p @ w2c[2, :3] + w2c[2, 3])

    v = view.direction
    if light.is_directional:
        l = light.direction
        e1 = perpendicular(l)
        e2 = np.cross(l, e1)
        use_entry = float(l @ v) >= 0.0
        total = 0.0
        for f, n in zip(faces, normals):
            c = float(n @ l)
            if abs(c) < 1e-12 or (c < 0) != use_entry:
                continue  # parallel to the light (zero projected area) or the other side
            tris = _fan(f)
            tri2 = np.stack([tris @ e1, tris @ e2], axis=-1)
            if view.orthographic:
                e_a, e_b = tri2[:, 1] - tri2[:, 0], tri2[:, 2] - tri2[:, 0]
                total += float(np.sum(0.5 * np.abs(e_a[:, 0] * e_b[:, 1] - e_a[:, 1] * e_b[:, 0])))
            else:
                z = depth(tris.reshape(-1, 3)).reshape(-1, 3)
                if np.any(z <= 0):
                    raise ValueError("region reaches behind the camera: clip it to the view frustum first")
                total += float(np.sum(integral_inverse_square_affine(tri2, z)))
        return k * total

    # point / spot: solid-angle parameterization on the unit plane along the axis towards the region
    L = np.asarray(light.position, dtype=np.float64)
    pts = np.concatenate(faces)
    axis = normalize(pts.mean(axis=0) - L)
    if np.any((pts - L) @ axis <= 1e-9 * max(1.0, float(np.max(np.linalg.norm(pts - L, axis=1))))):
        raise ValueError(f"light '{light.name}' lies inside or beside the view region: "
                         "Lloyd's limit needs every ray from the light to meet the region on one side")
    z_light = float(depth(L[None])[0])
    # (d/z) along a ray from the light: t/(z_L + b·t) is increasing when z_L > 0 -> max at the exit face
    use_exit = z_light > 0
    total = 0.0
    for f, n in zip(faces, normals):
        facing = (f.mean(axis=0) - L) @ n  # > 0: rays leave through this face
        if abs(facing) < 1e-12 * max(1.0, np.linalg.norm(f.mean(axis=0) - L)) or (facing > 0) != use_exit:
            continue
        tris3 = _fan(f)
        # central projection onto the plane axis·(x - L) = 1: q = L + (p - L)/s, s = axis·(p - L)
        sub3 = _subdivide(tris3, quadrature_levels)                  # (T, 3, 3) on the face
        s = (sub3 - L) @ axis
        q = L + (sub3 - L) / s[..., None]
        # on the unit plane z/s =: A(q) is affine in q and d/z = |q - L| / A, so the
        # integrand cos³α·(d/z)² = 1/(|q - L|·A²): exact ∬ 1/A² times 1/|q - L| at the centroid
        a_vals = depth(sub3.reshape(-1, 3)).reshape(s.shape) / s
        e1 = normalize(np.cross(axis, perpendicular(axis)))
        e2 = np.cross(axis, e1)
        q2 = np.stack([q @ e1, q @ e2], axis=-1)
        inv_r = 1.0 / np.linalg.norm(q.mean(axis=1) - L, axis=-1)
        total += float(np.sum(inv_r * integral_inverse_square_affine(q2, a_vals)))
    return k * total


def n_min_perpendicular(resolution, tan_half_fov: float, near: float, far: float) -> float:
    """Closed form for a light perpendicular to the view: Rx·Ry·ln(f/n)/(2·tanθ),
    θ the half field of view in the plane of the view and light directions."""
    rx, ry = resolution
    return rx * ry * math.log(far / near) / (2.0 * tan_half_fov)


def n_min_parallel(resolution, near: float, far: float) -> float:
    """Closed form for a light parallel to the view: Rx·Ry·(1 + 2·ln(f/n))."""
    rx, ry = resolution
    return rx * ry * (1.0 + 2.0 * math.log(far / near))


def m_min(n_min_texels: float, texels: float) -> float:
    """The smallest achievable maximum footprint (screen pixels per texel, linear)
    with ``texels`` texels: sqrt(N_min / N)."""
    if texels <= 0:
        raise ValueError("the texel budget must be positive")
    return math.sqrt(n_min_texels / texels)
