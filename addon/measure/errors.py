"""Shadow classification errors against ground truth, and temporal flicker (numpy only).

Images are (H, W) boolean arrays, True = in shadow, with a ``valid`` mask of the
pixels that show a surface (background and pixels the method could not evaluate
are left out of every count).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..warp.geometry import raster_position


def dilate(mask, radius: int) -> np.ndarray:
    """Binary dilation by a (2r+1)² square (Chebyshev distance <= radius)."""
    out = np.asarray(mask, dtype=bool).copy()
    for axis in (0, 1):
        src = out.copy()
        for k in range(1, int(radius) + 1):
            fwd = np.zeros_like(src)
            bwd = np.zeros_like(src)
            if axis == 0:
                fwd[k:] = src[:-k]
                bwd[:-k] = src[k:]
            else:
                fwd[:, k:] = src[:, :-k]
                bwd[:, :-k] = src[:, k:]
            out |= fwd | bwd
    return out


def shadow_edges(truth, valid) -> np.ndarray:
    """Valid pixels whose 4-neighbour (also valid) has the other true shadow state."""
    t = np.asarray(truth, dtype=bool)
    v = np.asarray(valid, dtype=bool)
    e = np.zeros_like(t)
    dy = (t[1:] != t[:-1]) & v[1:] & v[:-1]
    dx = (t[:, 1:] != t[:, :-1]) & v[:, 1:] & v[:, :-1]
    e[1:] |= dy
    e[:-1] |= dy
    e[:, 1:] |= dx
    e[:, :-1] |= dx
    return e & v


def edge_band(truth, valid, radius: int = 2) -> np.ndarray:
    """The pixels within ``radius`` pixels (Chebyshev) of a true shadow edge."""
    return dilate(shadow_edges(truth, valid), radius) & np.asarray(valid, dtype=bool)


@dataclass
class ErrorCounts:
    """Misclassified pixels. ``false_shadow``: method dark where truth is lit;
    ``false_light``: method lit where truth is dark. ``band_*``: the same within
    the edge band; rates are fractions of the pixels counted (valid / band)."""

    valid: int
    false_shadow: int
    false_light: int
    band: int
    band_false_shadow: int
    band_false_light: int
    true_shadow: int

    @property
    def errors(self) -> int:
        return self.false_shadow + self.false_light

    @property
    def error_rate(self) -> float:
        return self.errors / self.valid if self.valid else float("nan")

    @property
    def band_errors(self) -> int:
        return self.band_false_shadow + self.band_false_light

    @property
    def band_error_rate(self) -> float:
        return self.band_errors / self.band if self.band else float("nan")

    def to_json(self) -> dict:
        return {"valid": self.valid, "true_shadow": self.true_shadow,
                "false_shadow": self.false_shadow, "false_light": self.false_light,
                "error_rate": self.error_rate, "band": self.band,
                "band_false_shadow": self.band_false_shadow, "band_false_light": self.band_false_light,
                "band_error_rate": self.band_error_rate}


def classify(method, truth, valid, band_radius: int = 2) -> ErrorCounts:
    """Count false shadow / false light over ``valid`` pixels and within the
    band of ``band_radius`` pixels around the true shadow edges."""
    m = np.asarray(method, dtype=bool)
    t = np.asarray(truth, dtype=bool)
    v = np.asarray(valid, dtype=bool)
    if m.shape != t.shape or t.shape != v.shape:
        raise ValueError(f"image shapes differ: method {m.shape}, truth {t.shape}, valid {v.shape}")
    fs = m & ~t & v
    fl = ~m & t & v
    band = edge_band(t, v, band_radius)
    return ErrorCounts(valid=int(v.sum()), false_shadow=int(fs.sum()), false_light=int(fl.sum()),
                       band=int(band.sum()), band_false_shadow=int((fs & band).sum()),
                       band_false_light=int((fl & band).sum()), true_shadow=int((t & v).sum()))


ERROR_COLOURS = {
    "lit": (235, 235, 235), "shadow": (90, 90, 90), "background": (255, 255, 255),
    "false_shadow": (220, 30, 30), "false_light": (30, 110, 240),
}
"""Error image colours: correct lit / correct shadow greys, false shadow red, false light blue."""


def error_image(method, truth, valid) -> np.ndarray:
    """(H, W, 3) uint8 picture of the classification (colours: ERROR_COLOURS)."""
    m = np.asarray(method, dtype=bool)
    t = np.asarray(truth, dtype=bool)
    v = np.asarray(valid, dtype=bool)
    img = np.empty(m.shape + (3,), dtype=np.uint8)
    img[:] = ERROR_COLOURS["background"]
    img[v & ~t] = ERROR_COLOURS["lit"]
    img[v & t] = ERROR_COLOURS["shadow"]
    img[v & m & ~t] = ERROR_COLOURS["false_shadow"]
    img[v & ~m & t] = ERROR_COLOURS["false_light"]
    return img


@dataclass
class Flicker:
    """Temporal flicker over an animation: of the pixel transitions (consecutive
    frames, pixel valid in both) where the ground truth keeps its state, the
    fraction where the method's state changes."""

    stable_transitions: int
    flips: int

    @property
    def rate(self) -> float:
        return self.flips / self.stable_transitions if self.stable_transitions else float("nan")

    def to_json(self) -> dict:
        return {"stable_transitions": self.stable_transitions, "flips": self.flips, "rate": self.rate}


def flicker(method_frames, truth_frames, valid_frames) -> Flicker:
    """Flicker of (F, H, W) boolean frame stacks (F >= 2)."""
    m = np.asarray(method_frames, dtype=bool)
    t = np.asarray(truth_frames, dtype=bool)
    v = np.asarray(valid_frames, dtype=bool)
    if m.shape != t.shape or t.shape != v.shape or m.ndim != 3:
        raise ValueError(f"frame stacks must share one (F, H, W) shape: {m.shape}, {t.shape}, {v.shape}")
    stable = (t[1:] == t[:-1]) & v[1:] & v[:-1]
    flips = stable & (m[1:] != m[:-1])
    return Flicker(stable_transitions=int(stable.sum()), flips=int(flips.sum()))


def screen_motion(view_before, view_now, points) -> np.ndarray:
    """Pixels each world point moves on screen from ``view_before`` to ``view_now`` (both of one resolution): the
    camera's speed in the unit flicker meets it (``bench.cascade flicker --speeds``)."""
    pixels = [raster_position(v.world_to_clip, v.resolution, points) for v in (view_before, view_now)]
    return np.linalg.norm(pixels[1] - pixels[0], axis=1)


@dataclass
class FlickerSplit:
    """The two causes of pixel flicker under a moving camera, over the pixel transitions (frames k-1, k) that show
    one surface point through one map in both frames, where the ground truth keeps its state:

    * ``flips``: the method's state changes (the report's pixel flicker, on these pixels);
    * ``camera``: it changes between frame k-1 and frame k drawn with frame k-1's maps: only the camera moved, and an
      edge that stands still in the world but a texel off the truth's slides across the pixels;
    * ``world``: it changes between frame k drawn with frame k-1's maps and with its own: only the maps changed, the
      same surface point's state (world-consistent flicker, shimmer). ``flips`` <= ``camera`` + ``world``."""

    transitions: int
    flips: int
    camera: int
    world: int

    def to_json(self) -> dict:
        return {"transitions": self.transitions, "flips": self.flips, "camera": self.camera, "world": self.world}


def flicker_split(previous, held, current, truth_previous, truth_current, same) -> FlickerSplit:
    """:class:`FlickerSplit` of (T, H, W) boolean stacks, one layer per transition: the method's frame k-1, frame k
    drawn with frame k-1's maps (``held``) and with its own, the truth's two frames, and the pixels of frame k that
    show the surface point frame k-1 showed there through the same map (``same``)."""
    p, h, c, tp, tc, s = (np.asarray(a, dtype=bool) for a in (previous, held, current, truth_previous,
                                                              truth_current, same))
    if not p.shape == h.shape == c.shape == tp.shape == tc.shape == s.shape:
        raise ValueError(f"transition stacks must share one shape: {[a.shape for a in (p, h, c, tp, tc, s)]}")
    keep = s & (tp == tc)
    return FlickerSplit(int(keep.sum()), int((keep & (p != c)).sum()), int((keep & (p != h)).sum()),
                        int((keep & (h != c)).sum()))
