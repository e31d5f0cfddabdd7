"""What a method computed on the way, for overlays, reports and tests."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np


@dataclass
class Diagnostics:
    """theta, gamma: the light-view angle folded into [0, π/2] (GMNPR) and in [0, π] (Scherzer §4.4's γ); n_opt,
    lam: the warp's strength (Scherzer Eq. 1, GMNPR Eq. 8); body_vertices: B; warp_frustum_corners: P's 8 world
    corners (None where P reaches through infinity); fallbacks: (what, reason) wherever a method departed from its
    paper; extra: the rest."""

    method: str
    theta: Optional[float] = None
    gamma: Optional[float] = None
    n_opt: Optional[float] = None
    lam: Optional[float] = None
    body_vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    warp_frustum_corners: Optional[np.ndarray] = None
    fallbacks: list[tuple[str, str]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def fallback(self, what: str, reason: str) -> None:
        self.fallbacks.append((what, reason))
