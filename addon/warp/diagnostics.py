"""What a method computed on the way, for overlays, reports and tests.

A method reports some values it does not use itself: the warp frustum's
corners, its projection centre, B's middle vector. Computing them costs a
warped frame about 50 µs of its 500-900 (``bench.warp_compare``), so a method
may give them as :class:`OnRead`: computed the first time anything reads them,
then kept. Every way of reading gives the value: the attribute, ``extra[k]``,
``extra.get``, ``items()``, ``dict(extra)`` and ``to_json()``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np


class OnRead:
    """A reported value computed when first read (then kept)."""

    __slots__ = ("compute",)

    def __init__(self, compute: Callable[[], Any]):
        self.compute = compute


class Extra(dict):
    """``Diagnostics.extra``: a dict whose :class:`OnRead` values are computed
    on first read. (A dict subclass with its own ``__iter__`` is read through
    ``__getitem__`` by ``dict(extra)`` and ``{**extra}`` too.)"""

    def __getitem__(self, key):
        value = super().__getitem__(key)
        if isinstance(value, OnRead):
            value = value.compute()
            super().__setitem__(key, value)
        return value

    def __iter__(self):
        return super().__iter__()

    def get(self, key, default=None):
        return self[key] if key in self else default

    def items(self):
        return [(k, self[k]) for k in list(self.keys())]

    def values(self):
        return [self[k] for k in list(self.keys())]

    def copy(self) -> dict:
        return dict(self.items())


class _ComputedOnRead:
    """A :class:`Diagnostics` field that may be set to an :class:`OnRead`."""

    def __set_name__(self, owner, name):
        self.slot = "_" + name

    def __get__(self, obj, owner=None):
        if obj is None:
            return None                      # the field's default (dataclasses ask the class)
        value = obj.__dict__.get(self.slot)
        if isinstance(value, OnRead):
            value = obj.__dict__[self.slot] = value.compute()
        return value

    def __set__(self, obj, value):
        obj.__dict__[self.slot] = value


@dataclass
class Diagnostics:
    """theta: angle between light and view directions (radians, in [0, π/2] by
    symmetry, GMNPR's convention); gamma: the same in [0, π] (LiSPSM's γ,
    Scherzer §4.4); n_opt, lam: the warp's strength (Scherzer Eq. 1, GMNPR
    Eq. 8); body_vertices: B; warp_frustum_corners: the 8 world corners of the
    warp frustum P (if any); fallbacks: (what, reason) for every case a method
    handled otherwise than its paper; extra: the rest, by name."""

    method: str
    theta: Optional[float] = None
    gamma: Optional[float] = None
    n_opt: Optional[float] = None
    lam: Optional[float] = None
    body_vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    warp_frustum_corners: Optional[np.ndarray] = _ComputedOnRead()
    fallbacks: list[tuple[str, str]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=Extra)

    def __post_init__(self):
        if type(self.extra) is not Extra:
            self.extra = Extra(self.extra)

    def fallback(self, what: str, reason: str) -> None:
        self.fallbacks.append((what, reason))

    def to_json(self) -> dict:
        out = {
            "method": self.method,
            "theta_deg": None if self.theta is None else math.degrees(self.theta),
            "gamma_deg": None if self.gamma is None else math.degrees(self.gamma),
            "n_opt": self.n_opt,
            "lambda": self.lam,
            "body_vertices": _plain(self.body_vertices),
            "warp_frustum_corners": _plain(self.warp_frustum_corners),
            "fallbacks": [{"what": w, "reason": r} for w, r in self.fallbacks],
        }
        out.update(_plain(self.extra))
        return out


def _plain(v):
    """``v`` as JSON data (arrays and numpy scalars as lists and numbers)."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v
