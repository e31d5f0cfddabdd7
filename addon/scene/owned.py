"""Lixel's own objects in a scene (baked B, frusta, the geometry-node helpers).

They carry the custom property ``DEBUG_KEY`` and are never casters or
receivers: B would otherwise feed back into itself. The scene layer, the
render engine and the UI all ask :func:`is_debug_object`; no bpy import here.
"""
from __future__ import annotations

DEBUG_KEY = "lixel_debug"
"""Custom property marking Lixel's own debug objects; its value says what the object is."""


def is_debug_object(ob) -> bool:
    """True for an object (original or evaluated) Lixel made for debugging."""
    orig = getattr(ob, "original", None) or ob
    try:
        return DEBUG_KEY in orig.keys()
    except (AttributeError, ReferenceError, TypeError):
        return False
