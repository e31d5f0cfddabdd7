"""A convex polyhedron as its boundary, in plain Python floats, and the plane cut.

B and the polytopes around it have a dozen or two vertices, so numpy's fixed
cost per call outweighs the arithmetic; walking the faces in plain Python is
faster, and it keeps the faces closed by construction (every edge of the cut
has two faces), which vertex enumeration only approximates on near-degenerate
cuts.

A :class:`Brep` holds the vertices and, per facet, its plane (unit outward
normal, offset: ``normal . x <= offset`` inside) and its vertex loop,
counter-clockwise seen from outside. :func:`cut` intersects it with a
half-space. Facet planes are carried over, never recomputed from the
(possibly tiny) clipped polygons; only the cap gets the cutting plane.
"""
from __future__ import annotations

from typing import NamedTuple


class Brep(NamedTuple):
    """A closed convex polyhedron: ``vertices`` [(x, y, z)], and per facet
    ``normals`` [(nx, ny, nz)], ``offsets`` [o] and ``loops`` [[vertex index]].
    A cut shares the loops of the facets it keeps whole with the body it cut,
    so loops are never changed in place."""

    vertices: list
    normals: list
    offsets: list
    loops: list


class OpenCut(ValueError):
    """A cut whose new boundary does not close into one loop: the half-space
    passes through the polyhedron within the tolerance in a way the face walk
    cannot order (callers fall back to vertex enumeration)."""


def cut(b: Brep, normal, offset: float, tol: float) -> Brep | None:
    """``b`` ∩ {normal . x <= offset} (unit ``normal``); ``b`` itself when the
    half-space holds it, None when nothing with volume is left.

    Vertices within ``tol`` of the plane lie on it; when one does, the cut is
    ``_cut_through_vertices``. Otherwise every vertex is strictly inside or
    beyond, and each facet is kept whole (its loop shared, its vertex ids
    unchanged), dropped, or walked: every edge between the two sides gets its
    crossing point, computed once from the edge's endpoint inside, so both
    facets of the edge share it, and the crossings take the ids of the dropped
    vertices (then new ones), so nothing is renumbered unless fewer crossings
    than dropped vertices leave gaps. A facet's vertices beyond the plane are
    one run along its convex loop (the distance is affine on it), so a walked
    facet leaves the half-space once and comes back once: its new edge, from
    the crossing where it leaves to the one where it comes back, is a cap edge
    reversed, and the cap edges chain into the cap. A facet crossed more
    than twice (possible only through rounding on a near-degenerate body)
    leaves crossings off the cap and raises OpenCut."""
    nx, ny, nz = normal
    old = b.vertices
    d = [nx * x + ny * y + nz * z - offset for x, y, z in old]
    if max(d) <= tol:
        return b
    if min(d) >= -tol:
        return None
    if min(map(abs, d)) <= tol:
        return _cut_through_vertices(b, normal, offset, tol, d)

    beyond = {i for i, e in enumerate(d) if e > tol}
    verts = list(old)
    free = sorted(beyond, reverse=True)    # ids of the dropped vertices, for the crossings (lowest first)
    crossing: dict = {}                    # (inside, beyond) old vertex pair -> the crossing's id
    cap_next: dict = {}                    # cap edge: a facet's entry crossing -> its leaving one
    normals, offsets, loops = [], [], []
    for fn, fo, loop in zip(b.normals, b.offsets, b.loops):
        if beyond.isdisjoint(loop):        # kept whole
            new = loop
        elif beyond.issuperset(loop):      # cut away
            continue
        else:
            new = []
            p = loop[-1]
            p_out = p in beyond
            for q in loop:
                q_out = q in beyond
                if p_out != q_out:         # the edge p -> q crosses the plane
                    key = (q, p) if p_out else (p, q)
                    x = crossing.get(key)
                    if x is None:
                        w, v = key
                        (px, py, pz), (qx, qy, qz) = old[w], old[v]
                        t = d[w] / (d[w] - d[v])
                        point = (px + t * (qx - px), py + t * (qy - py), pz + t * (qz - pz))
                        if free:
                            x = free.pop()
                            verts[x] = point
                        else:
                            x = len(verts)
                            verts.append(point)
                        crossing[key] = x
                    new.append(x)
                    if p_out:
                        entry = x
                    else:
                        leave = x
                if not q_out:
                    new.append(q)
                p, p_out = q, q_out
            if entry in cap_next:
                raise OpenCut("two cap edges leave one vertex")
            cap_next[entry] = leave
        normals.append(fn)
        offsets.append(fo)
        loops.append(new)
    if len(cap_next) != len(crossing):
        raise OpenCut("a facet crosses the plane more than twice")
    normals.append(tuple(normal))
    offsets.append(offset)
    loops.append(_chain_cap(cap_next))
    if free:                               # fewer crossings than dropped vertices: close the gaps
        gone = set(free)
        live = [v for v in range(len(verts)) if v not in gone]
        index = dict(zip(live, range(len(live))))
        verts = [verts[v] for v in live]
        loops = [[index[v] for v in loop] for loop in loops]
    return Brep(verts, normals, offsets, loops)


def _chain_cap(cap_next: dict) -> list:
    """The cap's loop from its edges (vertex -> next vertex); OpenCut unless
    they close into one loop of at least three."""
    if len(cap_next) < 3:
        raise OpenCut("the cut leaves no cap")
    start = min(cap_next)
    cap = [start]
    nxt = cap_next[start]
    while nxt != start:
        if nxt is None or len(cap) > len(cap_next):       # (None: a facet loop left open upstream)
            raise OpenCut("the cap's edges do not close into one loop")
        cap.append(nxt)
        nxt = cap_next.get(nxt)
    if len(cap) != len(cap_next):
        raise OpenCut("the cap's edges form more than one loop")
    return cap


def _cut_through_vertices(b: Brep, normal, offset: float, tol: float, d: list) -> Brep:
    """``cut`` when a vertex lies on the plane (``d``: the vertices' signed
    distances to it; some vertex beyond, some inside). Each facet is walked
    once: kept, dropped, or cut where its edges cross the plane (a crossing
    point is shared by the two facets of its edge). The facets' new edges on
    the plane (between crossings and vertices on it), reversed, chain into the
    cap."""
    verts: list = []
    index: list = []                       # old vertex -> new index (-1: cut away)
    beyond, within, on = set(), set(), set()     # old vertices by side of the plane
    on_plane: set = set()                  # new indices of the vertices on the plane
    for i, (v, e) in enumerate(zip(b.vertices, d)):
        if e > tol:
            beyond.add(i)
            index.append(-1)
            continue
        if e < -tol:
            within.add(i)
        else:
            on.add(i)
            on_plane.add(len(verts))
        index.append(len(verts))
        verts.append(v)
    crossing: dict = {}                    # (lower, higher old index) -> new index

    normals, offsets, loops = [], [], []
    touching = []                          # the new loops with a vertex on the plane
    for fn, fo, loop in zip(b.normals, b.offsets, b.loops):
        if beyond.isdisjoint(loop):        # kept whole
            new = [index[v] for v in loop]
            if not on.isdisjoint(loop):
                touching.append(new)
        elif within.isdisjoint(loop):      # cut away (touching the plane at most)
            continue
        else:
            new = []
            k = len(loop)
            for i in range(k):
                a, c = loop[i], loop[i + 1 - k]
                if index[a] >= 0:
                    new.append(index[a])
                if (a in within and c in beyond) or (a in beyond and c in within):
                    key = (a, c) if a < c else (c, a)
                    x = crossing.get(key)
                    if x is None:
                        # From the endpoint with the lower index, so both facets get the same point.
                        (px, py, pz), (qx, qy, qz) = b.vertices[key[0]], b.vertices[key[1]]
                        t = d[key[0]] / (d[key[0]] - d[key[1]])
                        x = crossing[key] = len(verts)
                        verts.append((px + t * (qx - px), py + t * (qy - py), pz + t * (qz - pz)))
                        on_plane.add(x)
                    new.append(x)
            touching.append(new)
        normals.append(fn)
        offsets.append(fo)
        loops.append(new)

    # The cap: every facet edge p -> q lying on the plane is a cap edge q -> p.
    cap_next: dict = {}
    for loop in touching:
        p = loop[-1]
        p_on = p in on_plane
        for q in loop:
            q_on = q in on_plane
            if p_on and q_on:
                if q in cap_next:
                    raise OpenCut("two cap edges leave one vertex")
                cap_next[q] = p
            p, p_on = q, q_on
    normals.append(tuple(normal))
    offsets.append(offset)
    loops.append(_chain_cap(cap_next))
    return Brep(verts, normals, offsets, loops)


def clip(b: Brep, normals, offsets, tol: float) -> Brep | None:
    """``b`` cut by each half-space ``normal . x <= offset`` in turn (unit
    normals, as lists); None when nothing with volume is left."""
    for n, o in zip(normals, offsets):
        b = cut(b, n, o, tol)
        if b is None:
            return None
    return b


HEXAHEDRON_LOOPS = ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
"""The six quads of a hexahedron whose corners are ordered like
``geometry.UNIT_CUBE_CORNERS`` (near face first, x fastest, then y)."""


def hexahedron(corners) -> Brep:
    """A hexahedron (a view frustum, a box) from its 8 corners ordered like
    ``geometry.UNIT_CUBE_CORNERS``. A facet's normal is the cross product of
    its quad's diagonals (exact for a planar quad), turned outwards."""
    c = [tuple(map(float, p)) for p in corners]
    cx = sum(p[0] for p in c) / 8
    cy = sum(p[1] for p in c) / 8
    cz = sum(p[2] for p in c) / 8
    normals, offsets, loops = [], [], []
    for quad in HEXAHEDRON_LOOPS:
        a, b, e, f = (c[i] for i in quad)
        ux, uy, uz = e[0] - a[0], e[1] - a[1], e[2] - a[2]
        vx, vy, vz = f[0] - b[0], f[1] - b[1], f[2] - b[2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        length = (nx * nx + ny * ny + nz * nz) ** 0.5
        if length == 0.0:
            raise OpenCut("a face of the hexahedron has no area")
        nx, ny, nz = nx / length, ny / length, nz / length
        mx = (a[0] + b[0] + e[0] + f[0]) / 4
        my = (a[1] + b[1] + e[1] + f[1]) / 4
        mz = (a[2] + b[2] + e[2] + f[2]) / 4
        if nx * (cx - mx) + ny * (cy - my) + nz * (cz - mz) > 0:      # pointing inwards
            nx, ny, nz, quad = -nx, -ny, -nz, quad[::-1]
        normals.append((nx, ny, nz))
        offsets.append(nx * mx + ny * my + nz * mz)
        loops.append(list(quad))
    return Brep(c, normals, offsets, loops)


def directed_edges(loops) -> dict:
    """(from, to) vertex pair -> the facet whose loop runs along it."""
    owner = {}
    for f, loop in enumerate(loops):
        for i in range(len(loop)):
            owner[(loop[i - 1], loop[i])] = f
    return owner
