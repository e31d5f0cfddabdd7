"""The warp methods, by name. Each is ``method(view, light, body, options) -> ShadowSetup``;
those in ``SCENE_METHODS`` also take the scene (the cascade builds one B per split)."""
from typing import Callable

from ..types import WarpOptions
from .cascade import adaptive_splits, cascade
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
VISIBLE_RANGE_METHODS = frozenset({"psm", "lispsm", "gmnpr", "glpr", "cascade"})
"""The methods that read ``WarpOptions.visible_depth_range``: PSM's d_R (``post_perspective.nearest_visible_depth``),
LiSPSM's, GMNPR's and GLPR's Δz = "visible" (``warp_frustum.eye_depth_range``), the cascade's range to split
(``partition.splits``); the panel shows the Visible Range for them and checks it against the camera's clip range."""


def reads_surface(method: str, options: WarpOptions) -> bool:
    """Whether ``method`` reads the seen surface, ``VisibleRegion.surface`` and ``normals`` (the pre-pass read back
    whole): plane_optimal for its default plane (no ``planes`` given), the cascade for its adaptive splits."""
    return (method == "plane_optimal" and not options.planes) or (method == "cascade" and adaptive_splits(options))
