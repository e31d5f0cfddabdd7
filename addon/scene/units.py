"""Lengths as the user reads them: Lixel computes in Blender units, and every length a message, note or readout
prints is shown in the scene's units (Scene properties > Units), as Blender's own fields show it."""
from __future__ import annotations

import bpy

BASE_UNIT = {"METRIC": (1.0, " m"), "IMPERIAL": (0.3048, "'")}
"""Each unit system's base length unit (metres per unit, symbol), for a length too small for its named units."""


def length_text(value: float, scene) -> str:
    """A length in Blender units as Blender's own fields show it: in ``scene``'s unit system and Unit Scale
    (Scene properties > Units: at 0.01, 100 units are 1 m), to 3 digits; "m" where the scene is gone. A length
    Blender's units would round off by more than 1 % (below a micrometre: "0 m") or reaches a billion metres
    or feet (to_string writes "30000000532 km") is given in metres or feet: "1e-09 m", "3e+13 m"."""
    units = getattr(scene, "unit_settings", None)
    if units is None:
        return f"{value:.3g} m"
    if units.system == "NONE":
        return f"{value:.3g}"
    metres = value * units.scale_length
    text = bpy.utils.units.to_string(units.system, "LENGTH", metres, precision=3)
    per_unit, symbol = BASE_UNIT[units.system]
    rounded_off = abs(bpy.utils.units.to_value(units.system, "LENGTH", text) - metres) > 0.01 * abs(metres)
    if not rounded_off and abs(metres) < 1e9 * per_unit:
        return text
    return f"{metres / per_unit:.3g}{symbol}"
