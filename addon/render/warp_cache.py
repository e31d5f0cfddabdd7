"""B and the warp of recent frames, kept while nothing they depend on changes.

``focused_body`` and ``compute`` (addon.warp) are pure functions of the view, the light,
the scene's boxes, the visible region the camera pre-pass read back, the
method and the warp options. A frame whose inputs all equal an earlier
frame's (F12 again on an unchanged scene, a redraw that moved nothing) takes
that frame's B and setup instead of computing them again; a moved camera or
light, an edited object or another setting computes them anew. The scene's
boxes are compared by identity (``InstanceSet.bounds`` is made once per
instance set, so an unchanged scene hands out the same object), everything
else by value.
"""
from __future__ import annotations

from dataclasses import fields, is_dataclass

import numpy as np


def value_key(obj):
    """A hashable key equal for equal values: dataclasses by their fields,
    arrays by their shape, type and bytes, sequences item by item."""
    if isinstance(obj, np.ndarray):
        return ("array", obj.shape, obj.dtype.str, obj.tobytes())
    if is_dataclass(obj) and not isinstance(obj, type):
        return (type(obj).__name__,) + tuple(value_key(getattr(obj, f.name)) for f in fields(obj))
    if isinstance(obj, (list, tuple)):
        return tuple(value_key(v) for v in obj)
    if isinstance(obj, dict):
        return tuple(sorted((k, value_key(v)) for k, v in obj.items()))
    return obj


class WarpCache:
    """(B, setup) of the last ``KEEP`` distinct frames. ``computes`` counts the
    frames that computed them (tests read it)."""

    KEEP = 4

    def __init__(self):
        self._entries: dict = {}
        self.computes = 0

    def clear(self) -> None:
        self._entries.clear()

    def get(self, bounds, inputs: tuple, make):
        """``make()`` -> (B, setup) for the scene boxes ``bounds`` and the other
        ``inputs`` (method, view, light, options, visible region), or an earlier
        frame's result for equal ones. Errors (an empty body) are raised every
        time, never kept."""
        key = (id(bounds), value_key(inputs))
        hit = self._entries.pop(key, None)
        if hit is not None and hit[0] is bounds:
            self._entries[key] = hit              # the most recent last
            return hit[1]
        got = make()
        self.computes += 1
        while len(self._entries) >= self.KEEP:
            self._entries.pop(next(iter(self._entries)))
        self._entries[key] = (bounds, got)
        return got


_shared = None


def shared_warps() -> WarpCache:
    """The process-wide warp cache (the render engine's frames)."""
    global _shared
    if _shared is None:
        _shared = WarpCache()
    return _shared
