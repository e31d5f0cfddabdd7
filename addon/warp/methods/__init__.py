"""The warp methods, by name. Each is ``method(view, light, body, options) -> ShadowSetup``;
those in ``SCENE_METHODS`` also take the scene (the cascade builds one B per split)."""
from __future__ import annotations

from typing import Callable

from .cascade import cascade
from .lispsm import glpr, gmnpr, lispsm
from .plane_optimal import plane_optimal
from .psm import psm
from .uniform import uniform

METHODS: dict[str, Callable] = {
    "uniform": uniform,
    "psm": psm,
    "lispsm": lispsm,
    "gmnpr": gmnpr,
    "glpr": glpr,
    "plane_optimal": plane_optimal,
    "cascade": cascade,
}
SCENE_METHODS = frozenset({"cascade"})
SURFACE_METHODS = frozenset({"plane_optimal", "cascade"})
"""Methods that read the seen surface, ``VisibleRegion.surface`` and ``normals`` (the pre-pass read back whole)."""
