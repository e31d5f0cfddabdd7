"""Cascaded shadow maps: z-splits of the view, each with its own B and warp.

Scherzer §3 names the companion of warping: "a partitioning of the view
frustum into subsets, each rendered into its own shadow map"; GMNPR's
introduction names it too, and engines ship it (PSSM, CSM, LiSPSM per cascade).
By Lloyd's analysis a few log-spaced splits, each warped, come close to the
physical limit m_min that no single map can approach (``addon/measure/lloyd.py``).

The pipeline (:func:`cascade`):

1. **The depth range** [z_n, z_f]: where a shadowed receiver can be seen
   (``partition.splits.tightened_depth_range``).
2. **The splits** C_0..C_N: the practical scheme with ``cascade_lambda``
   (PSSM), then, with ``cascade_adaptive``, moved to minimise the largest
   predicted error (``partition.adaptive``); with ``cascade_stable``, the λ
   splits of the range widened to whole octaves, which stand still while the
   camera moves (``partition.stable``).
3. **Each split** i gets the camera clipped to [C_i, C_(i+1) + band]
   (``split_view``), its own intersection body B_i (Scherzer §4.1 over the
   split's part of the view: R_i = V_i ∩ S_r ∩ L, B_i = hull(R_i ∪ light) ∩ S_c)
   and its own warp: ``cascade_warp``, or with "auto" the one of uniform, psm,
   lispsm and gmnpr whose maps predict the lowest error (Lloyd's factor at its
   maximum over R_i, ``partition.adaptive.max_error``). With
   ``cascade_stable`` every split of a sun is a uniform map on a texel grid
   fixed in the world (``partition.stable.stable_sun_map``): a warp moves with
   the camera and cannot be snapped.
4. **The texels** (``partition.budget``): a map of the configured size per
   map, or the configured size shared by predicted error.
5. **One ShadowSetup**: the splits' maps in order, each carrying
   ``view_depth_range`` = (C_i, C_(i+1)), so the ranges tile [near, far] (the
   first starts at the camera's near plane, the last ends at its far plane).
   A point takes the first map whose clip volume and range hold it.

**Seams.** Split i's map (i < N - 1) also holds the first ``band_i`` of split
i + 1 (its B is built over [C_i, C_(i+1) + band_i], band_i =
``cascade_blend``·(C_(i+1) - C_i)) and says so in ``ShadowMap.blend_band``;
the shading pass fades from it into split i + 1's map across that band, so
the change of resolution at a split's end is not a visible line.

**How many maps.** The shading pass reads at most ``MAX_MAPS`` maps. A point
light whose splits each need several cube faces can ask for more; the
cascade then makes fewer splits (recorded in ``diagnostics.fallbacks``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..body import IntersectionBody, intersection_body
from ..frame import body_light_angles
from ..partition.adaptive import max_error, minimax_splits
from ..partition.budget import shared_sizes
from ..partition.splits import practical_splits, split_region, split_view, tightened_depth_range
from ..partition.stable import stable_depth_range, stable_spot_map, stable_sun_map
from ..diagnostics import Diagnostics, OnRead
from ..types import EmptyBodyError, Light, SceneBounds, ShadowMap, ShadowSetup, View, WarpError, WarpOptions
from ..visibility import VisibleRegion
from .lispsm import gmnpr, lispsm
from .psm import psm
from .uniform import uniform

SPLIT_WARPS = {"uniform": uniform, "lispsm": lispsm, "gmnpr": gmnpr, "psm": psm}
"""The warps a split may take (``WarpOptions.cascade_warp``, or all of them with
"auto"), in the order "auto" prefers them when their errors tie."""
TIE = 1e-6
"""Relative difference of predicted errors below which "auto" keeps the warp it
prefers: symmetric configurations (light exactly perpendicular to the view,
where LiSPSM's and GMNPR's λ agree) must not pick by rounding noise."""
MAX_MAPS = 8
"""The most maps the shading pass reads (``addon.gpu.shaders.MAX_MAPS``)."""
OVERLAP = 1e-4
"""Each split's B reaches this fraction of its depths beyond both of its ends:
a receiver exactly at a split's depth (a floor seen straight from above) then
meets the split's view in a volume, not only in a face the culling may drop."""


@dataclass
class Split:
    """One split: its depths, the camera clipped to it, its B, and its maps."""

    near: float                 # C_i
    far: float                  # C_(i+1)
    band: float                 # how far past C_(i+1) its maps also hold (the blend band)
    view: View                  # the camera clipped to [C_i, C_(i+1) + band]
    body: Optional[IntersectionBody]   # B_i; None: nothing visible in the split
    warp: str = "uniform"
    setup: Optional[ShadowSetup] = None
    predicted_error: float = 0.0


def allowed_warps(options: WarpOptions) -> list:
    """The warps a split may take: ``cascade_warp``, every one for "auto", the
    uniform map alone when stable."""
    if options.cascade_stable:
        return ["uniform"]
    return list(SPLIT_WARPS) if options.cascade_warp == "auto" else [options.cascade_warp]


def split_options(options: WarpOptions, size: tuple[int, int]) -> WarpOptions:
    """The options a split's warp runs with: its own map size."""
    return dataclasses.replace(options, shadow_map_size=size)


def split_setup(warp: str, view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """A split's maps by ``warp``; a stable cascade's sun or spot split on its
    world-fixed texel grid (``partition.stable``)."""
    stable = None
    if options.cascade_stable and light.is_directional:
        stable = stable_sun_map(view, light, body, options.shadow_map_size, linear_z=options.linear_z)
    elif options.cascade_stable and light.type == "SPOT":
        stable = stable_spot_map(light, body, options.shadow_map_size, options.max_frustum_angle)
    if stable is not None:
        return ShadowSetup([stable], Diagnostics("uniform", body_vertices=body.vertices))
    setup = SPLIT_WARPS[warp](view, light, body, options)
    if options.cascade_stable and light.type == "SPOT":
        setup.diagnostics.fallback("stable", f"this split reaches beyond {math.degrees(options.max_frustum_angle):.0f}° "
                                             f"around spot '{light.name}''s axis: its maps are not texel-snapped")
    return setup


def split_body(view: View, light: Light, scene: SceneBounds, near: float, far: float,
               visible: Optional[VisibleRegion]) -> tuple[View, Optional[IntersectionBody]]:
    """The camera clipped to eye depths [near, far] (a split and its band) and
    its B, focused on its part of the ``visible`` region when there is one
    (None: nothing visible there)."""
    start, end = near * (1.0 - OVERLAP), far * (1.0 + OVERLAP)
    clipped = split_view(view, max(start, view.near * (1.0 - OVERLAP)), end)
    seen = None if visible is None else split_region(visible, start, end)
    if seen is not None and seen.is_empty:
        return clipped, None
    try:
        return clipped, intersection_body(clipped, light, scene, seen)
    except EmptyBodyError:
        return clipped, None


def build_split(view: View, light: Light, scene: SceneBounds, near: float, far: float, band: float,
                options: WarpOptions, warps: Optional[list] = None, visible: Optional[VisibleRegion] = None,
                bodies: Optional[dict] = None) -> Split:
    """Split [near, far] (holding ``band`` more): its B (kept in ``bodies`` by
    depths, if given) and the warp that predicts the lowest error among
    ``warps`` (default: those ``options`` allows)."""
    key = (near, far + band)
    if bodies is None or key not in bodies:
        made = split_body(view, light, scene, near, far + band, visible)
        if bodies is None:
            bodies = {}
        bodies[key] = made
    clipped, body = bodies[key]
    split = Split(near, far, band, clipped, body)
    if body is None:
        return split
    sub = split_options(options, options.shadow_map_size)
    for name in warps or allowed_warps(options):
        setup = split_setup(name, clipped, light, body, sub)
        error = max_error(clipped, light, setup, body.visible_vertices)
        if split.setup is None or error < split.predicted_error * (1.0 - TIE):
            split.warp, split.setup, split.predicted_error = name, setup, error
    return split


def split_depths(view: View, light: Light, scene: SceneBounds, body: IntersectionBody,
                 options: WarpOptions) -> tuple[np.ndarray, list, str]:
    """C_0..C_N and the splits built on them (step 2 of the pipeline), with
    the scheme that placed them. The adaptive search keeps each split's warp
    from the λ splits (its ranking barely moves with the split's ends); the
    splits it settles on choose again among every allowed warp."""
    z_n, z_f = tightened_depth_range(view, light, body, options)
    if options.cascade_stable:
        z_n, z_f = stable_depth_range(z_n, z_f, view)
    depths = practical_splits(z_n, z_f, options.cascade_splits, options.cascade_lambda)
    bodies: dict = {}                     # each split's view and B, by its depths: the search revisits them

    def splits_at(c: np.ndarray) -> list:
        last = len(c) - 2
        return [build_split(view, light, scene, a, b, 0.0 if i == last else options.cascade_blend * (b - a),
                            options, None, body.visible, bodies) for i, (a, b) in enumerate(zip(c[:-1], c[1:]))]

    splits = splits_at(depths)
    if not options.cascade_adaptive or options.cascade_splits == 1 or options.cascade_stable:
        return depths, splits, "practical"
    kept = [s.warp for s in splits]

    def error_of(i: int, a: float, b: float) -> float:
        band = 0.0 if i == len(kept) - 1 else options.cascade_blend * (b - a)
        return build_split(view, light, scene, a, b, band, options, [kept[i]], body.visible, bodies).predicted_error

    moved, _ = minimax_splits(error_of, depths, [s.predicted_error for s in splits],
                              options.cascade_budget == "shared")
    if np.array_equal(moved, depths):
        return depths, splits, "adaptive"
    return moved, splits_at(moved), "adaptive"


def map_sizes(splits: list, options: WarpOptions) -> list:
    """Each map's (w, h), split by split (step 4): the configured size, or
    with a shared budget the configured size's texels shared by predicted error."""
    per_map = [(s.predicted_error, m) for s in splits if s.setup is not None for m in s.setup.maps]
    if options.cascade_budget == "per_map":
        return [options.shadow_map_size] * len(per_map)
    return shared_sizes(options.shadow_map_size, [error for error, _ in per_map])


def resized(split: Split, light: Light, sizes: list, options: WarpOptions) -> list:
    """The split's maps at their budgeted sizes; texel-snapped (stable) maps
    are made again, since their window snaps to whole texels of that size."""
    if not options.cascade_stable or all(tuple(m.size) == tuple(s) for m, s in zip(split.setup.maps, sizes)):
        return [dataclasses.replace(m, size=tuple(s)) for m, s in zip(split.setup.maps, sizes)]
    remade = split_setup(split.warp, split.view, light, split.body, split_options(options, tuple(sizes[0])))
    return [dataclasses.replace(m, size=tuple(s)) for m, s in zip(remade.maps, sizes)]


def cascade_maps(view: View, light: Light, splits: list, options: WarpOptions) -> tuple[list, list]:
    """Every split's maps in order with their view depth ranges, blend bands
    and sizes (step 5), and which split each map belongs to. The ranges tile
    [near, far]: a split with nothing visible leaves its range to the split before."""
    sizes = iter(map_sizes(splits, options))
    filled = [i for i, s in enumerate(splits) if s.setup is not None]
    maps, owner = [], []
    for k, i in enumerate(filled):
        split = splits[i]
        start = view.near if k == 0 else split.near
        end = view.far if k == len(filled) - 1 else splits[filled[k + 1]].near
        blends = k + 1 < len(filled) and filled[k + 1] == i + 1
        for m in resized(split, light, [next(sizes) for _ in split.setup.maps], options):
            maps.append(dataclasses.replace(m, view_depth_range=(start, end),
                                            blend_band=split.band if blends else 0.0, role=f"split{i}:{m.role}"))
            owner.append(i)
    return maps, owner


def predicted_errors(splits: list, maps: list, owner: list, options: WarpOptions) -> list:
    """Each split's predicted error at its maps' final size (None for an empty
    split): a map's error falls as one over its side, E ∝ 1/sqrt(texels)."""
    w0, h0 = options.shadow_map_size
    out = []
    for i, s in enumerate(splits):
        if s.setup is None:
            out.append(None)
            continue
        w, h = maps[owner.index(i)].size
        out.append(s.predicted_error * math.sqrt(w0 * h0 / (w * h)))
    return out


def fitting_splits(view: View, light: Light, scene: SceneBounds, body: IntersectionBody, options: WarpOptions,
                   diag: Diagnostics) -> tuple[np.ndarray, list, str]:
    """``split_depths`` with as many splits as the shading pass can read the
    maps of (``MAX_MAPS``): fewer when each split needs several cube faces."""
    count = options.cascade_splits
    while True:
        depths, splits, scheme = split_depths(view, light, scene, body,
                                              dataclasses.replace(options, cascade_splits=count))
        needed = sum(len(s.setup.maps) for s in splits if s.setup is not None)
        if needed <= MAX_MAPS or count == 1:
            return depths, splits, scheme
        diag.fallback("splits", f"{count} splits need {needed} maps and the shading pass reads {MAX_MAPS}: "
                                f"{count - 1} splits")
        count -= 1


def cascade(view: View, light: Light, body: IntersectionBody, options: WarpOptions,
            scene: Optional[SceneBounds] = None) -> ShadowSetup:
    """The cascade's maps: the module's pipeline, step by step."""
    if scene is None:
        raise WarpError("the cascade builds one intersection body per split from the scene: call it through compute()")
    theta, gamma = body_light_angles(view, light, body)
    diag = Diagnostics("cascade", theta, gamma, body_vertices=body.vertices)
    if options.cascade_stable and light.type == "POINT":
        diag.fallback("stable", f"point light '{light.name}': its cube faces turn with B, so its maps are not "
                                "texel-snapped")
    depths, splits, scheme = fitting_splits(view, light, scene, body, options, diag)
    if all(s.setup is None for s in splits):
        raise EmptyBodyError("no split of the view holds a visible receiver")
    maps, owner = cascade_maps(view, light, splits, options)
    for i, s in enumerate(splits):
        for what, why in (s.setup.diagnostics.fallbacks if s.setup is not None else []):
            diag.fallback(f"split {i}: {what}", why)
    errors = predicted_errors(splits, maps, owner, options)
    diag.extra.update({
        "splits": [float(d) for d in depths],
        "split_scheme": scheme,
        "split_warps": [s.warp if s.setup is not None else None for s in splits],
        "split_predicted_error": errors,
        "predicted_max_error": max(e for e in errors if e is not None),
        "map_splits": owner,
        "split_bodies": OnRead(lambda: [s.body.vertices if s.body is not None else None for s in splits]),
        "split_body_faces": OnRead(lambda: [list(s.body.faces) if s.body is not None else None for s in splits]),
        "split_frusta": OnRead(lambda: [s.setup.diagnostics.warp_frustum_corners if s.setup is not None else None
                                          for s in splits]),
        "budget": options.cascade_budget,
        "stable": options.cascade_stable,
    })
    return ShadowSetup(maps, diag)
