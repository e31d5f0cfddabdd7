"""What a method computed on the way, for overlays, reports and tests. A value the
method does not use itself (the warp frustum's corners, its projection centre)
may be given as :class:`OnRead`: computed when first read, however it is read
(the attribute, ``extra[k]``, ``get``, ``items()``, ``dict(extra)``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np


class OnRead:
    """A reported value computed when first read (then kept)."""

    __slots__ = ("compute",)

    def __init__(self, compute: Callable[[], Any]):
        self.compute = compute


class Extra(dict):
    """``Diagnostics.extra``: a dict whose :class:`OnRead` values are computed on first
    read (its own ``__iter__`` makes ``dict(extra)`` read through ``__getitem__``)."""

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
    """theta, gamma: the light-view angle folded into [0, π/2] (GMNPR) and in [0, π]
    (Scherzer §4.4's γ); n_opt, lam: the warp's strength (Scherzer Eq. 1, GMNPR
    Eq. 8); body_vertices: B; warp_frustum_corners: P's 8 world corners; fallbacks:
    (what, reason) wherever a method departed from its paper; extra: the rest."""

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
