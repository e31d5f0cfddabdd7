"""The analytic footprint next to the rendered error, and why they disagree.

The analytic footprint (``addon.measure.footprint``) is what the matrices
promise: screen pixels spanned by one texel at each visible point. It is
summarised over the *lit-facing* points only, as the shared rendered-error
harness does (``bench.rendered_error``): counted by the ground truth, lit in
it, and turned to the light by at least :data:`NDL_MIN` (n·l). A surface
grazing the light has an unbounded footprint whatever the warp (projection
aliasing, Stamminger-Drettakis §1.1: cos β in the denominator), so without the
threshold its max and share above 1 say nothing about the method.

The rendered error is what the pipeline delivers against exact ray-cast
shadows. Where the two rank a method against its reference differently, the
error's anatomy says why: where the wrong pixels are (at true shadow edges,
where the footprint decides, or away from them, where depth and bias decide),
which way they are wrong (false light: shadows lost; false shadow: acne or
spread shadows), whether a map served them at all, and whether they lie on
grazing surfaces that the footprint statistic leaves out.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

from addon.measure import footprint_stats
from addon.measure.errors import edge_band
from bench.rendered_error import LIT_FACING as NDL_MIN  # one threshold for the report and the harness

AGREE_FOOTPRINT = 1.25
"""Footprint ratios within this factor of 1 count as 'about the same footprint'."""
AGREE_ERROR = 1.25
"""Error ratios within this factor of 1 count as 'about the same error'."""


def n_dot_l(points: np.ndarray, normals: np.ndarray, light) -> np.ndarray:
    """n·l at world ``points`` (..., 3) with unit ``normals``; NaN where points are NaN."""
    p = np.asarray(points, dtype=np.float64)
    flat = p.reshape(-1, 3)
    ok = np.all(np.isfinite(flat), axis=1)
    to_light = np.full_like(flat, np.nan)
    to_light[ok] = -light.rays_to(flat[ok])
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    return np.einsum("ij,ij->i", n, to_light).reshape(p.shape[:-1])


def facing(gt, light) -> np.ndarray:
    """The ground truth's counted pixels turned to the light by at least NDL_MIN (lit or not)."""
    ndl = n_dot_l(gt.points, gt.normals, light)
    return gt.valid & (np.nan_to_num(ndl, nan=-1.0) >= NDL_MIN)


def lit_facing(gt, light) -> np.ndarray:
    """The ground truth's lit pixels turned to the light by at least NDL_MIN."""
    return facing(gt, light) & ~gt.shadow


def footprint_summary(fp_image: np.ndarray, mask: np.ndarray) -> dict:
    """Statistics (max, p95, mean, share above 1) of a footprint image over ``mask``."""
    return footprint_stats(fp_image[mask]).to_json()


@dataclass
class ErrorAnatomy:
    """Where a method's wrong pixels are (fractions of its wrong pixels)."""

    errors: int
    false_light: float          # lit where the truth is dark
    at_edges: float             # within the band around true shadow edges
    interior_false_light: float  # away from edges and false light: whole shadows lost
    interior_false_shadow: float  # away from edges and false shadow: acne, shadows spread or spilled
    unserved: float             # no map served the pixel
    grazing: float              # on surfaces with n·l < NDL_MIN (left out of the footprint statistic)
    edge_false_light: float     # of the wrong pixels at edges, the false-light share (shadows shrunk, light leaking)
    edge_footprint_p95: float   # analytic footprint p95 over the facing pixels at true shadow edges (both sides)

    def to_json(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(self).items()}


def anatomy(shadow, truth, counted, facing_mask, map_index, fp_image, band_radius: int = 2) -> ErrorAnatomy:
    """Where the wrong pixels are; ``facing_mask``: pixels turned to the light
    (lit or not), the rest counts as grazing."""
    s, t, c = (np.asarray(a, dtype=bool) for a in (shadow, truth, counted))
    wrong = c & (s != t)
    fl = wrong & t
    band = edge_band(t, c, band_radius)
    n = int(wrong.sum())
    edge_fp = fp_image[band & facing_mask]
    edge_fp = edge_fp[np.isfinite(edge_fp)]

    def share(mask) -> float:
        return float((mask & wrong).sum() / n) if n else float("nan")

    at_edges = int((wrong & band).sum())

    return ErrorAnatomy(
        errors=n, false_light=share(fl), at_edges=share(band),
        interior_false_light=share(fl & ~band), interior_false_shadow=share(wrong & ~t & ~band),
        unserved=share(np.asarray(map_index) < 0), grazing=share(~facing_mask),
        edge_false_light=float((fl & band).sum() / at_edges) if at_edges else float("nan"),
        edge_footprint_p95=float(np.percentile(edge_fp, 95)) if len(edge_fp) else float("nan"))


def _ratio(a, b) -> Optional[float]:
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return None
    return a / b


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


SIGNIFICANCE = 3.0
"""How many standard deviations of counting noise (Poisson: the square root of
the count) separate a rendered error from the one the footprint predicts before
they are said to disagree."""


def _trend(ratio: float, factor: float) -> str:
    return "smaller" if ratio < 1 / factor else "larger" if ratio > factor else "about the same"


def explain(rec: dict, ref: dict, ref_label: str) -> Optional[str]:
    """A sentence when the analytic footprint and the rendered error rank ``rec``
    against ``ref`` differently (None when they agree or cannot be told apart).

    Both are records of the report (``footprint_lit``, ``errors``, ``anatomy``,
    ``fallbacks``). To first order a shadow edge is misclassified over a band as
    wide as a texel's footprint, so the footprint ratio fa predicts
    ``nb · fa`` wrong pixels where the reference has nb. The two disagree when
    the footprint and the rendered error point different ways (smaller, about
    the same, larger: ratios beyond AGREE_FOOTPRINT / AGREE_ERROR) and the
    method's wrong pixels na lie more than SIGNIFICANCE standard deviations of
    counting noise from that prediction; the sentence then names what the
    error's anatomy shows."""
    fa = _ratio(rec["footprint_lit"]["p95"], ref["footprint_lit"]["p95"])
    ea, eb = rec["errors"]["error_rate"], ref["errors"]["error_rate"]
    if fa is None or ea is None or eb is None:
        return None
    na = rec["errors"].get("false_light", 0) + rec["errors"].get("false_shadow", 0)
    nb = ref["errors"].get("false_light", 0) + ref["errors"].get("false_shadow", 0)
    er = ea / eb if eb > 0 else (1.0 if ea == 0 else math.inf)
    predicts, got = _trend(fa, AGREE_FOOTPRINT), _trend(er, AGREE_ERROR)
    expected = nb * fa
    if predicts == got or abs(na - expected) <= SIGNIFICANCE * math.sqrt(expected + 1.0):
        return None
    a = rec["anatomy"]
    head = (f"footprint p95 {fa:.2f}× {ref_label}'s predicts {'a ' if predicts != 'about the same' else ''}"
            f"{predicts} error (about {expected:.0f} wrong pixels against {ref_label}'s {nb}); rendered "
            f"{'∞' if math.isinf(er) else f'{er:.2f}'}× ({na}).")
    why = []
    for what, reason in rec.get("fallbacks", []):
        why.append(f"the method fell back ({what}: {reason})")
    for what, reason in rec.get("notes", []):
        why.append(f"the method notes {what}: {reason}")
    if a["unserved"] is not None and a["unserved"] > 0.25:
        why.append(f"{_pct(a['unserved'])} of its wrong pixels are served by no map (a coverage gap)")
    if a["interior_false_light"] is not None and a["interior_false_light"] > 0.5:
        why.append(f"{_pct(a['interior_false_light'])} of its wrong pixels are false light away from shadow edges: "
                   f"whole shadows lost, which the depth comparison (depth range, precision, bias) decides and the "
                   f"footprint does not measure")
    if a["interior_false_shadow"] is not None and a["interior_false_shadow"] > 0.5:
        why.append(f"{_pct(a['interior_false_shadow'])} of its wrong pixels are false shadow away from shadow edges: "
                   f"acne or spilled shadow (bias too small for its texels, or depth precision)")
    if a["grazing"] is not None and a["grazing"] > 0.3:
        why.append(f"{_pct(a['grazing'])} of its wrong pixels lie on surfaces grazing the light (n·l < {NDL_MIN}), "
                   f"which the footprint statistic leaves out")
    fe = _ratio(a["edge_footprint_p95"], ref["anatomy"]["edge_footprint_p95"])
    if a["at_edges"] is not None and a["at_edges"] > 0.5 and fe is not None:
        edges = f"{_pct(a['at_edges'])} of its wrong pixels are at shadow edges"
        edge_trend = _trend(fe, AGREE_FOOTPRINT)
        if edge_trend == got == "about the same":
            why.append(f"{edges}, and there its footprint p95 is {fe:.2f}× {ref_label}'s, about the same: the pixels "
                       f"that carry the shadow edges do not get the smaller texels the lit surfaces get on average")
        elif edge_trend == got:
            why.append(f"{edges}, and there its footprint p95 is {fe:.2f}× {ref_label}'s: the edges fall where its "
                       f"texels are {edge_trend} than over the lit surfaces as a whole")
        elif a["edge_false_light"] is not None and max(a["edge_false_light"], 1 - a["edge_false_light"]) >= 0.7:
            kind = ("false light (shadows shrunk, light leaking past casters)" if a["edge_false_light"] >= 0.7
                    else "false shadow (shadows grown)")
            why.append(f"{edges}, {_pct(max(a['edge_false_light'], 1 - a['edge_false_light']))} of them {kind}, "
                       f"where its footprint p95 is {fe:.2f}× {ref_label}'s: one-sided edge errors come from the "
                       f"depth "
                       f"comparison at the edges (a bias in each map's own depth units means a different offset in "
                       f"the world), not from the texel size")
        else:
            why.append(f"{edges}, both kinds alike, where its footprint p95 is {fe:.2f}× {ref_label}'s: the texel "
                       f"footprint does not explain this difference")
    if not why:
        why.append(f"its wrong pixels: {_pct(a['false_light'] or 0)} false light, {_pct(a['at_edges'] or 0)} at "
                   f"shadow edges; no single cause stands out")
    return head + " " + "; ".join(why) + "."
