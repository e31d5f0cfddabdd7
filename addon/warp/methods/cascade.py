"""Cascaded shadow maps (Scherzer §3.3: "a partitioning of the view frustum into subsets, each rendered into its own
shadow map"; GMNPR §1), :func:`cascade` (docs/papers.md, ``addon/warp/methods/cascade.py``): split depths C_0..C_N
(``partition``); split i the view clipped to [C_i, C_(i+1) + band_i], its B_i (Scherzer §4.1) and warp; one
ShadowSetup of every split's maps, ``view_depth_range`` tiling [near, far], at most ``MAX_MAPS`` maps."""
from __future__ import annotations

import dataclasses
import itertools
import math
from typing import Optional

import numpy as np

from ..body import IntersectionBody, intersection_body
from ..diagnostics import Diagnostics
from ..frame import light_cone
from ..partition.adaptive import max_error, minimax_splits
from ..partition.budget import shared_sizes
from ..partition.receivers import (TAIL, filter_losses, footprint_p95, footprint_p95s, footprints, grazing, receivers,
                                   spun, turned)
from ..partition.splits import practical_splits, split_region, split_view, tightened_depth_range
from ..partition.stable import stable_depth_range, stable_spot_map, stable_sun_map
from ..types import MAX_MAP_SIDE, EmptyBodyError, Light, SceneBounds, ShadowSetup, View, WarpError, WarpOptions
from ..visibility import VisibleRegion
from .common import body_diagnostics
from .lispsm import gmnpr, lispsm
from .psm import psm
from .uniform import uniform
from .warp_frustum import TURNS

SPLIT_WARPS = {"uniform": uniform, "lispsm": lispsm, "gmnpr": gmnpr, "psm": psm}
"""A split's warps, in the order "auto" prefers them on a tie."""
TIE, MARGIN, SWEEPS, FRACTIONS = 1e-6, 0.03, 2, (0.2, 0.4, 0.6, 0.8)
"""Relative differences of Lloyd's m (rounding noise) and of the receivers' p95 (a sample) taken as ties; the split
search's sweeps, each trying every inner split depth at these fractions of its range (``searched_depths``)."""
ASPECTS = (2.0, 0.5)
"""Each single map's texels also laid out this much wider (or taller), w·h kept, for the receivers' footprint to pick:
on a wall nearly edge-on to the light a texel's length is ds/cos α (PSM §1.1), ds its side along one image axis."""


def stretched(size: tuple) -> list[tuple[int, int]]:
    """``size``'s texels w·h laid out by each of ``ASPECTS`` (w:h that much wider), those within ``MAX_MAP_SIDE``."""
    laid = [(int(round(size[0] * math.sqrt(a))), int(round(size[1] / math.sqrt(a)))) for a in ASPECTS]
    return [s for s in laid if max(s) <= MAX_MAP_SIDE]


def single(setup: ShadowSetup, **changed) -> ShadowSetup:
    """``setup`` with the fields ``changed`` of its one map."""
    return dataclasses.replace(setup, maps=[dataclasses.replace(setup.maps[0], **changed)])


MAX_MAPS = 8
"""The most maps the shading pass reads (``addon.gpu.shaders.MAX_MAPS``)."""
OVERLAP = 1e-4
"""Each split's B reaches this fraction of its depths past both ends (a floor at a split depth meets it in a volume)."""


@dataclasses.dataclass
class Split:
    near: float                 # C_i
    far: float                  # C_(i+1)
    band: float                 # how far past C_(i+1) its maps also hold
    view: View                  # the camera clipped to [C_i, C_(i+1) + band]
    body: Optional[IntersectionBody]   # B_i; None: nothing visible in the split
    warp: str = "uniform"
    setup: Optional[ShadowSetup] = None
    predicted_error: float = 0.0
    tried: list = dataclasses.field(default_factory=list)   # (warp, setup) of each warp it tried


def split_setup(warp: str, view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """A split's maps by ``warp`` (PSM without its λ guard: docs/papers.md), or a stable sun or spot split's, snapped."""
    stable, size = options.cascade_stable and light.type != "POINT", options.shadow_map_size
    snapped = None if not stable else stable_sun_map(light, body, view, size) if light.is_directional \
        else stable_spot_map(light, body, size, options.max_frustum_angle)
    if snapped is not None:
        return ShadowSetup([snapped], Diagnostics("uniform", body_vertices=body.vertices))
    setup = SPLIT_WARPS[warp](view, light, body, dataclasses.replace(options, lambda_guard="off") if warp == "psm"
                              else options)
    if stable:                  # a spot split wider than max_frustum_angle
        setup.diagnostics.fallback("stable", f"this split reaches beyond {math.degrees(options.max_frustum_angle):.0f}° "
                                             f"around spot '{light.name}''s axis: its maps are not texel-snapped")
    return setup


@dataclasses.dataclass
class Trials:
    """The splits one ``split_depths`` tries, each part (B_i, a warp's maps and their error, turns, footprints) made
    ``once``, kept by its depths: Lloyd's rounds and the split search meet most depth pairs again."""
    view: View
    light: Light
    scene: SceneBounds
    options: WarpOptions
    visible: Optional[VisibleRegion] = None
    seen: Optional[tuple] = None        # the ``receivers`` from C_0 on (None: their normals unknown)
    made: dict = dataclasses.field(default_factory=dict)
    cube_axis: Optional[np.ndarray] = None   # every split's B's (the whole B's: docs/papers.md, "One cube")
    scale: float = 0.0                       # every split's B's at least (the whole B's: its padding, tolerances)

    def once(self, key: tuple, make):
        """``make()``, called the first time ``key`` is asked for."""
        if key not in self.made:
            self.made[key] = make()
        return self.made[key]

    def body(self, near: float, far: float) -> tuple[View, Optional[IntersectionBody]]:
        """The view clipped to eye depths [near, far] and its B on its part of ``visible`` (None: nothing seen)."""
        start, end = near * (1.0 - OVERLAP), far * (1.0 + OVERLAP)
        clipped = split_view(self.view, max(start, self.view.near * (1.0 - OVERLAP)), end)
        seen = None if self.visible is None else split_region(self.visible, start, end)
        if seen is not None and seen.is_empty:
            return clipped, None
        try:
            return clipped, dataclasses.replace(intersection_body(clipped, self.light, self.scene, seen, self.scale),
                                                cube_axis=self.cube_axis)
        except EmptyBodyError:
            return clipped, None

    def split(self, near: float, far: float, band: float, warps: Optional[list] = None, scored: bool = True) -> Split:
        """Split [near, far] holding ``band`` more, by the warp of least predicted error among ``warps`` (or all; not
        ``scored``: one warp, its error unread)."""
        end, options = far + band, self.options
        view, body = self.once(("body", near, end), lambda: self.body(near, end))
        split = Split(near, far, band, view, body)
        if warps is None:
            warps = ["uniform"] if options.cascade_stable else list(SPLIT_WARPS) if options.cascade_warp == "auto" \
                else [options.cascade_warp]
        for name in warps if body is not None else []:
            setup = self.once(("maps", near, end, name), lambda: split_setup(name, view, self.light, body, options))
            error = 0.0 if not scored else self.once(("m", near, end, name),
                                                     lambda: max_error(view, self.light, setup, body.visible_vertices))
            if split.setup is None or error < split.predicted_error * (1.0 - TIE):
                split.warp, split.setup, split.predicted_error = name, setup, error
            split.tried.append((name, setup))
        return split

    def splits_at(self, c: np.ndarray, warps: Optional[list] = None, scored: bool = True) -> list:
        """The splits between the depths ``c``, split i with the warps allowed or ``warps[i]``, and a band of
        ``cascade_blend``·(C_(i+1) - C_i) (none for the last)."""
        return [self.split(a, b, 0.0 if i == len(c) - 2 else self.options.cascade_blend * (b - a), None if warps is None
                           else [warps[i]], scored) for i, (a, b) in enumerate(zip(c[:-1], c[1:]))]

    def candidates(self, split: Split, far: float, laid: bool = True) -> list:
        """(warp, setup, ``footprints`` at the receivers at eye depths [C_i, ``far``)) of each warp ``split`` tried
        (Lloyd's pick first), each single map ``turned`` to B_i's hull and (``laid``) to its ``grazing`` ones and (a
        point or spot light's, edges known) ``spun`` by ``TURNS``, and (``laid``) each of those ``stretched``."""
        maps = sorted(split.tried, key=lambda t: t[1] is not split.setup)
        *at, edges = self.seen                  # the receivers' arrays, and apart the edge samples (point, direction)
        kept, kept_edges = ((d >= split.near) & (d < far) for d in map(self.view.eye_depth, (at[0], edges[:, 0])))
        seen = (*(x[kept] for x in at), edges[kept_edges])
        spin = laid and len(seen[4]) and not self.light.is_directional
        for w, m in [(w, m) for w, m in maps if len(m.maps) == 1]:
            hull = self.once(("turned", split.near, split.far + split.band, w),
                             lambda: turned(m.maps[0].matrix, split.body.vertices))
            maps += [(w, single(m, matrix=t)) for t in hull + (turned(m.maps[0].matrix, split.body.vertices,
                                                                      grazing(m, seen, self.light)) if laid else [])
                     + (spun(m.maps[0].matrix, split.body.vertices, TURNS) if spin else [])]
        maps += [(w, single(m, size=size)) for w, m in maps if len(m.maps) == 1 and laid
                 for size in stretched(m.maps[0].size)]
        unique = {}       # (a later copy of a map never wins: the first least wins); by receivers, matrices and sizes
        for w, m in maps:
            unique.setdefault((kept.tobytes(), *((p.matrix.tobytes(), tuple(p.size)) for p in m.maps)), (w, m))
        new = {key: m for key, (_, m) in unique.items() if key not in self.made}     # (footprints made once each)
        self.made.update(zip(new, footprints(list(new.values()), seen) if new else []))
        setups = [m for _, m in unique.values()]  # each weighed by the filter gain it loses at the known shadow edges
        return [(w, m, self.made[key] * k) for (key, (w, m)), k in zip(unique.items(), filter_losses(setups, seen))]

    def least_footprint(self, splits: list) -> tuple[list, list]:
        """``splits`` with the maps among their ``candidates`` of least p95 at the receivers (coordinate descent from
        Lloyd's picks, two sweeps; kept if ``MARGIN`` below theirs) and their footprints there (none: none known)."""
        depth = np.zeros(0) if self.seen is None else self.view.eye_depth(self.seen[0])
        scored = [(s, self.once(("candidates", s.near, s.far, s.band, s.warp, *(w for w, _ in s.tried)),
                                lambda: self.candidates(s, s.far))) for s in splits
                  if s.setup is not None and np.any((depth >= s.near) & (depth < s.far))]
        pick = [0] * len(scored)
        for i in [*range(len(scored))] * 2:
            others = [c[k][2] for j, ((_, c), k) in enumerate(zip(scored, pick)) if j != i]
            pick[i] = int(np.argmin(footprint_p95s(others, [f for *_, f in scored[i][1]])))
        picked, lloyds = ([c[k][2] for (_, c), k in zip(scored, p)] for p in (pick, [0] * len(scored)))
        if not (scored and footprint_p95(picked) < (1.0 - MARGIN) * footprint_p95(lloyds)):
            pick, picked = [0] * len(scored), lloyds
        for (s, c), k in [(sc, k) for sc, k in zip(scored, pick) if k]:          # (Lloyd's pick keeps its error)
            s.warp, s.setup, _ = c[k]
            s.predicted_error = max_error(s.view, self.light, s.setup, s.body.visible_vertices)
        return splits, picked

    def least(self, split: Split, far: float) -> np.ndarray:
        """The footprints of ``split``'s unlaid candidate of least p95 at the receivers at eye depths [C_i, ``far``)."""
        def least() -> np.ndarray:
            fs = [f for *_, f in self.candidates(split, far, False)]
            return fs[int(np.argmin(footprint_p95s([], fs)))] if fs else np.zeros(0)
        return self.once(("least", split.near, far, split.warp), least)

    def searched_depths(self, start: np.ndarray, warps: list) -> np.ndarray:
        """``start`` after ``SWEEPS`` coordinate sweeps of the inner ones over ``FRACTIONS`` of their neighbours'
        log range (linear if orthographic), kept where the ``TAIL`` p95 of the splits' ``least`` falls by ``MARGIN``."""
        def tail(c: np.ndarray) -> float:          # (the splits' Lloyd's m unread: ``least`` scores them)
            splits = self.splits_at(c, warps, scored=False)
            return footprint_p95([self.least(s, far) for s, far in zip(splits, [*c[1:-1], math.inf])], TAIL)

        c, best = start, tail(start)
        for _, k, f in itertools.product(range(SWEEPS), range(1, len(start) - 1), FRACTIONS):
            trial = c.copy()
            trial[k] = c[k - 1] + (c[k + 1] - c[k - 1]) * f if self.view.orthographic \
                else c[k - 1] * (c[k + 1] / c[k - 1]) ** f
            error = tail(trial)
            if error < best * (1.0 - MARGIN):
                c, best = trial, error
        return c


def adaptive_splits(options: WarpOptions) -> bool:
    """Whether the split depths move (``minimax_splits``) and the maps are then scored at the seen receivers."""
    return options.cascade_adaptive and options.cascade_splits > 1 and not options.cascade_stable


def split_depths(view: View, light: Light, scene: SceneBounds, body: IntersectionBody,
                 options: WarpOptions) -> tuple[np.ndarray, list, str]:
    """C_0..C_N, their splits and the scheme. The adaptive search keeps each split's warp from the λ splits; where it
    settles, every warp competes again (and their turned maps at known receivers: ``least_footprint``)."""
    if options.cascade_stable:      # B of the view frustum: the visible region's tiles jump as the camera moves
        body = intersection_body(view, light, scene)
    z_n, z_f = tightened_depth_range(view, light, body, options)
    z_n, z_f = stable_depth_range(z_f, view) if options.cascade_stable else (z_n, z_f)
    depths = practical_splits(z_n, z_f, options.cascade_splits, options.cascade_lambda)
    seen = receivers(view, light, body.visible, z_n, math.inf, scene) if adaptive_splits(options) else None
    trials = Trials(view, light, scene, options, body.visible, seen,
                    cube_axis=None if light.is_directional else light_cone(body.vertices, light.position)[0],
                    scale=body.scale)
    splits = trials.splits_at(depths)
    if not adaptive_splits(options):
        return depths, splits, "practical"
    kept = [s.warp for s in splits]
    moved = minimax_splits(lambda c: [s.predicted_error for s in trials.splits_at(c, kept)], depths,
                           [s.predicted_error for s in splits], options.cascade_budget == "shared")
    splits, seen = trials.least_footprint(splits if np.array_equal(moved, depths) else trials.splits_at(moved))
    found = trials.searched_depths(moved, [s.warp for s in splits]) if seen else moved
    if found is moved:
        return moved, splits, "adaptive"
    searched, now = trials.least_footprint(trials.splits_at(found))
    better = footprint_p95(now, TAIL) < footprint_p95(seen, TAIL) and footprint_p95(now) <= footprint_p95(seen) and \
        sum(len(s.setup.maps) for s in searched if s.setup) <= MAX_MAPS
    return (found, searched, "receivers") if better else (moved, splits, "adaptive")


def cascade_maps(view: View, light: Light, splits: list, options: WarpOptions) -> tuple[list, list]:
    """Every split's maps at their budgeted sizes, with depth ranges tiling [near, far] (an empty split's range goes
    to the one before), blend bands, and which split owns each."""
    filled = [i for i, s in enumerate(splits) if s.setup is not None]
    errors = [splits[i].predicted_error for i in filled for _ in splits[i].setup.maps]
    given = [m.size for i in filled for m in splits[i].setup.maps]               # per_map: PSSM's texels each
    sizes = iter(given if options.cascade_budget == "per_map" else shared_sizes(given, errors))
    maps, owner = [], []
    for k, i in enumerate(filled):
        split = splits[i]
        start = view.near if k == 0 else split.near
        end = view.far if k == len(filled) - 1 else splits[filled[k + 1]].near
        band = split.band if k + 1 < len(filled) and filled[k + 1] == i + 1 else 0.0
        own = [tuple(next(sizes)) for _ in split.setup.maps]
        made = split.setup.maps
        if options.cascade_stable and any(tuple(m.size) != s for m, s in zip(made, own)):   # re-snap to the size
            made = split_setup(split.warp, split.view, light, split.body,
                               dataclasses.replace(options, shadow_map_size=own[0])).maps
        maps += [dataclasses.replace(m, size=size, view_depth_range=(start, end), blend_band=band,
                                     role=f"split{i}:{m.role}") for m, size in zip(made, own)]
        owner += [i] * len(own)
    return maps, owner


def fitting_splits(view: View, light: Light, scene: SceneBounds, body: IntersectionBody, options: WarpOptions,
                   diag: Diagnostics) -> tuple[np.ndarray, list, str]:
    """``split_depths`` with one split fewer while their maps exceed ``MAX_MAPS``."""
    for count in range(options.cascade_splits, 0, -1):
        depths, splits, scheme = split_depths(view, light, scene, body,
                                              dataclasses.replace(options, cascade_splits=count))
        needed = sum(len(s.setup.maps) for s in splits if s.setup is not None)
        if needed <= MAX_MAPS or count == 1:
            return depths, splits, scheme
        diag.fallback("splits", f"{count} splits need {needed} maps and the shading pass reads {MAX_MAPS}: "
                                f"{count - 1} splits")


def cascade(view: View, light: Light, body: IntersectionBody, options: WarpOptions,
            scene: Optional[SceneBounds] = None) -> ShadowSetup:
    """The cascade's maps (module docs)."""
    if scene is None:
        raise WarpError("the cascade builds one intersection body per split from the scene: call it through compute()")
    diag = body_diagnostics("cascade", view, light, body)
    if options.cascade_stable and light.type == "POINT":
        diag.fallback("stable", f"point light '{light.name}': its cube faces turn with B, so its maps are not "
                                "texel-snapped")
    depths, splits, scheme = fitting_splits(view, light, scene, body, options, diag)
    if all(s.setup is None for s in splits):
        raise EmptyBodyError("no split of the view holds a visible receiver")
    maps, owner = cascade_maps(view, light, splits, options)
    filled = [s.setup is not None for s in splits]
    errors = [s.predicted_error * math.sqrt(np.prod(options.shadow_map_size) / np.prod(maps[owner.index(i)].size))
              if f else None for i, (s, f) in enumerate(zip(splits, filled))]   # E ∝ 1/sqrt(texels) at its size
    for i, s in enumerate(splits):
        for what, why in (s.setup.diagnostics.fallbacks if filled[i] else []):
            diag.fallback(f"split {i}: {what}", why)
    diag.extra.update(
        splits=[float(d) for d in depths], split_scheme=scheme, map_splits=owner, split_predicted_error=errors,
        split_warps=[s.warp if f else None for s, f in zip(splits, filled)],
        predicted_max_error=max(e for e in errors if e is not None), budget=options.cascade_budget,
        stable=options.cascade_stable, split_bodies=[s.body.vertices if s.body is not None else None for s in splits],
        split_body_faces=[list(s.body.faces) if s.body is not None else None for s in splits],
        split_frusta=[s.setup.diagnostics.warp_frustum_corners if f else None for s, f in zip(splits, filled)])
    return ShadowSetup(maps, diag)
