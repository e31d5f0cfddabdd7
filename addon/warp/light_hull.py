"""What a light adds to a body: its frustum L and hull(P ∪ light).

L is the spot cone, bounded by a circumscribed pyramid (all space for suns and
point lights). hull(P ∪ light) is the body P swept towards the light: for B
(body.py) P is R, the part of the view that holds receivers, and everything
that can shadow R lies in hull(R ∪ light) (Scherzer §4.1, Fig. 5). It is built
exactly, with the light in homogeneous coordinates (w = 0 for a sun), as
half-spaces (for culling) and as a boundary (:mod:`.brep`, for cutting).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .brep import Brep, OpenCut, directed_edges
from .polyhedron import float_rows
from .types import Light

CONE_SIDES = 16
"""The spot cone is bounded by a circumscribed pyramid with this many sides."""

SUN_FACING = 1e-12
"""A facet faces a sun when cos(angle to the direction towards it) exceeds this."""


def cone_halfspaces(apex, axis, full_angle) -> tuple[np.ndarray, np.ndarray]:
    """(normals (k, 3), offsets (k,)) of a pyramid circumscribing the cone
    (apex, axis, full angle), k = CONE_SIDES."""
    ax, ay, az = (float(c) for c in axis)
    length = math.sqrt(ax * ax + ay * ay + az * az)
    ax, ay, az = ax / length, ay / length, az / length
    # u: perpendicular to the axis, away from the coordinate axis it is least aligned with; v = a x u.
    e = min(range(3), key=lambda i: abs((ax, ay, az)[i]))
    ex, ey, ez = (1.0 if i == e else 0.0 for i in range(3))
    ux, uy, uz = ay * ez - az * ey, az * ex - ax * ez, ax * ey - ay * ex
    length = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / length, uy / length, uz / length
    vx, vy, vz = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    # Tangent planes of a regular pyramid circumscribing the cone: the cone's
    # half-angle widened so the cone fits inside the polygon (secant of pi/k).
    # Side i's normal is cos(widened) (cos θ_i u + sin θ_i v) - sin(widened) a
    # (unit: the radial part ⊥ the axis), all sides in one product.
    widened = math.atan(math.tan(full_angle / 2) / math.cos(math.pi / CONE_SIDES))
    c, s = math.cos(widened), math.sin(widened)
    n = _CONE_ROWS @ np.array([[c * ux, c * uy, c * uz], [c * vx, c * vy, c * vz], [-s * ax, -s * ay, -s * az]])
    return n, n @ np.asarray(apex, dtype=np.float64)


_CONE_ANGLES = 2 * math.pi * np.arange(CONE_SIDES) / CONE_SIDES
_CONE_ROWS = np.stack([np.cos(_CONE_ANGLES), np.sin(_CONE_ANGLES), np.ones(CONE_SIDES)], axis=1)
"""(cos θ_i, sin θ_i, 1) per side of the pyramid."""


def light_halfspaces(light: Light, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L relative to ``origin``: the half-spaces of the light's frustum (only spots have one)."""
    if light.type != "SPOT":
        return np.zeros((0, 3)), np.zeros(0)
    return cone_halfspaces(light.position - origin, light.direction, light.spot_angle)


class LightHull(NamedTuple):
    """hull(P ∪ light) for a convex polytope P: its half-spaces, and the
    pieces its boundary is made of (see ``light_hull``)."""

    normals: np.ndarray
    offsets: np.ndarray
    """The half-spaces ``normals @ x <= offsets``: P's facets that do not face the light, then one per
    side (each silhouette edge whose facet does not hold the light)."""
    body: Brep
    """P's boundary, whose facets and vertices the other fields refer to."""
    kept: list
    """Indices of P's facets that do not face the light."""
    sides: list | None
    """(a, c, g) per silhouette edge: P's edge a -> c in the loop of facet g, which does not face the
    light while the facet across the edge does. None when P's loops do not close."""
    holding: set
    """The kept facets whose plane holds the light (within the tolerance): their sides lie in their own
    plane, so each such facet grows over them instead of getting separate sides."""
    light: tuple
    """The light in homogeneous coordinates."""

    def brep(self, cap: tuple | None = None) -> Brep:
        """The boundary of hull(P ∪ light): P's facets that do not face the
        light and the sides, each side a triangle (a point light) or, for a sun
        (u the direction towards it), a strip along u to the plane ``cap`` =
        (m, h), m . x = h, which closes the body (m . u > 0, and P strictly on
        the side m . x < h: B uses the face of S_c the light leaves it by, so
        S_c's own clip has one plane less to cut). A facet holding the light
        takes its sides into its own loop (its run of silhouette edges a1 ...
        ak becomes a1, light, ak, or a1, a1', ak', ak for a sun), so no two
        facets share a plane. P itself when no facet faces the light (a point
        light inside or on P)."""
        b = self.body
        if self.sides is None:
            raise OpenCut("P's loops do not close: the hull has no boundary")
        if not self.sides:
            return b
        x, y, z, w = self.light
        sun = w == 0
        apex = -1                                  # ids < 0: the light, and -2 - v for v raised to the cap
        silhouette = {(a, c) for a, c, _ in self.sides}
        normals = [b.normals[g] for g in self.kept]
        offsets = [b.offsets[g] for g in self.kept]
        loops, cap_next = [], {}
        for g in self.kept:
            loop = b.loops[g]
            if g not in self.holding:
                loops.append(list(loop))
                continue
            k = len(loop)
            on = [(loop[i - 1], loop[i]) in silhouette for i in range(k)]     # edge into loop[i]
            starts = [i for i in range(k) if on[i] and not on[i - 1]]
            if not any(on):
                loops.append(list(loop))
                continue
            if len(starts) != 1:
                raise OpenCut("a facet holding the light sees it across more than one run of edges")
            i = starts[0] - 1                      # the run is loop[i] -> ... -> loop[j]
            j = i + 1
            while on[(j + 1) % k]:
                j += 1
            first, last = loop[i % k], loop[j % k]
            grown = [first, -2 - first, -2 - last, last] if sun else [first, apex, last]
            grown += [loop[(j + 1 + t) % k] for t in range(k - (j - i) - 1)]
            loops.append(grown)
            if sun:
                cap_next[-2 - last] = -2 - first
        rows = iter(zip(self.normals[len(self.kept):].tolist(), self.offsets[len(self.kept):].tolist()))
        for a, c, g in self.sides:
            if g in self.holding:
                continue
            n, o = next(rows)
            normals.append(tuple(n))
            offsets.append(o)
            if sun:
                loops.append([c, a, -2 - a, -2 - c])
                cap_next[-2 - c] = -2 - a
            else:
                loops.append([c, a, apex])
        if sun:
            (mx, my, mz), h = cap
            start = min(cap_next)
            ring, v = [start], cap_next[start]
            while v != start and len(ring) <= len(cap_next):
                ring.append(v)
                v = cap_next.get(v, start)
            if len(ring) != len(cap_next) or v != start:
                raise OpenCut("the silhouette is not one loop")
            normals.append((mx, my, mz))
            offsets.append(h)
            loops.append(ring)
            rate = mx * x + my * y + mz * z
        # Number the vertices the loops use: P's, then the light or the raised ones.
        index, verts = {}, []
        for loop in loops:
            for v in loop:
                if v in index:
                    continue
                index[v] = len(verts)
                if v >= 0:
                    verts.append(b.vertices[v])
                elif v == apex:
                    verts.append((x / w, y / w, z / w))
                else:                              # v moved along u onto the cap plane
                    px, py, pz = b.vertices[-2 - v]
                    t = (h - (mx * px + my * py + mz * pz)) / rate
                    verts.append((px + t * x, py + t * y, pz + t * z))
        return Brep(verts, normals, offsets, [[index[v] for v in loop] for loop in loops])


def light_hull(b: Brep, light_h, tol: float) -> LightHull:
    """hull(P ∪ light) for a convex polyhedron P (its boundary ``b``), the
    light in homogeneous coordinates (x, y, z, w), w = 0 for a light at
    infinity (then (x, y, z) is the unit direction towards it).

    Its half-spaces are P's facets that do not face the light plus, through
    each silhouette edge (a facet g that does not face the light next to one, f,
    that does), the plane through that edge and the light. With F(x) = n_f . x - o_f
    and G likewise, that plane is the positive combination

        σ = -G(light) · F + F(light) · G,     σ(light) = 0,

    of two half-spaces that hold P, so it holds P exactly, however short the
    edge (no cross product of its endpoints); any such σ holds hull(P ∪ light).
    A facet within the tolerance of the light counts as not facing it, and
    holds it: its σ is its own plane, so it adds none. When P's loops do not
    close (a near-degenerate clip), facets sharing two vertices count as
    neighbours and the hull has half-spaces but no boundary (``LightHull.sides``
    is None)."""
    x, y, z, w = (float(c) for c in light_h)
    s = [nx * x + ny * y + nz * z - o * w for (nx, ny, nz), o in zip(b.normals, b.offsets)]
    threshold = tol if w != 0 else SUN_FACING
    facing = [v > threshold for v in s]
    kept = [g for g in range(len(b.loops)) if not facing[g]]
    holding = {g for g in kept if s[g] >= -threshold}
    owner = directed_edges(b.loops)
    pairs, sides = [], []
    for g in kept:
        loop = b.loops[g]
        for i in range(len(loop)):
            a, c = loop[i - 1], loop[i]
            f = owner.get((c, a))
            if f is None:
                sides = None
                break
            if facing[f]:
                sides.append((a, c, g))
                if g not in holding:
                    pairs.append((f, g))
        if sides is None:
            break
    if sides is None:
        loops = [set(loop) for loop in b.loops]
        pairs = [(f, g) for g in kept if g not in holding
                 for f in range(len(b.loops)) if facing[f] and len(loops[f] & loops[g]) >= 2]
    normals = [b.normals[g] for g in kept]
    offsets = [b.offsets[g] for g in kept]
    for f, g in pairs:
        wf, wg = -s[g], s[f]
        (fx, fy, fz), (gx, gy, gz) = b.normals[f], b.normals[g]
        nx, ny, nz = wf * fx + wg * gx, wf * fy + wg * gy, wf * fz + wg * gz
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length == 0.0:               # f and g opposite: P is flat there, and g alone bounds it
            nx, ny, nz, length, wf, wg = gx, gy, gz, 1.0, 0.0, 1.0
        normals.append((nx / length, ny / length, nz / length))
        offsets.append((wf * b.offsets[f] + wg * b.offsets[g]) / length)
    return LightHull(float_rows(normals), np.array(offsets, dtype=np.float64),
                     b, kept, sides, holding, (x, y, z, w))
