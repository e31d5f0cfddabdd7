"""What in a .blend is Lixel's own: the debug objects (baked B, frusta, the
geometry-node helpers) and every datablock Lixel made for them.

* Lixel's debug objects carry ``DEBUG_KEY``: they are never casters or
  receivers, or B would feed back into itself (:func:`is_debug_object`).
* Every datablock Lixel makes carries ``MADE_KEY``, whose value is the name
  Lixel gave it. Lixel finds its datablocks by that mark, never by name alone:
  when a user's datablock already has the name, Lixel's gets Blender's next free
  name ("Lixel B.001") and the user's is never touched (:func:`lixel_datablock`).
* The mark also holds the datablock's own name when it was made (``NAME_KEY``).
  A copy the user makes (Shift+D copies custom properties) gets another name, as
  does a datablock the user renames to keep: either is the user's from then on,
  and Lixel neither reuses, rewrites nor removes it.

The scene layer, the render engine and the UI all ask here; no bpy import.
"""
from __future__ import annotations

import re

DEBUG_KEY = "lixel_debug"
"""Custom property marking Lixel's own debug objects; its value says what the object is."""
MADE_KEY = "lixel_made"
"""Custom property on every datablock Lixel made; its value is the name Lixel gave it."""
NAME_KEY = "lixel_made_name"
"""Custom property on every datablock Lixel made: the datablock's own name then (a copy's or a renamed one's differs)."""
LEGACY_KEYS = (DEBUG_KEY, "lixel_version")
"""Marks that files saved before MADE_KEY existed put on Lixel's objects, node groups and materials."""


def is_debug_object(ob) -> bool:
    """True for an object (original or evaluated) Lixel made for debugging."""
    orig = getattr(ob, "original", None) or ob
    try:
        return DEBUG_KEY in orig.keys()
    except (AttributeError, ReferenceError, TypeError):
        return False


def is_lixel_made(idb) -> bool:
    """True for a datablock Lixel made (and may change or remove)."""
    if idb is None:
        return False
    try:
        keys = idb.keys()
    except (AttributeError, ReferenceError, TypeError):
        return False
    if MADE_KEY in keys:
        return idb.get(NAME_KEY, idb.name) == idb.name
    return any(k in keys for k in LEGACY_KEYS)


def made_as(idb, name: str) -> bool:
    """True when ``idb`` is the datablock Lixel made under ``name`` (files from before the mark: named so)."""
    made = idb.get(MADE_KEY)
    return is_lixel_made(idb) and (made == name if made is not None else idb.name == name)


def find_made(datablocks, name: str):
    """The datablock of ``datablocks`` (a ``bpy.data`` collection) that Lixel made
    under ``name``, or None. A user's datablock of that name is never returned."""
    idb = datablocks.get(name)
    if idb is not None and getattr(idb, "library", None) is None and made_as(idb, name):
        return idb
    for idb in datablocks:
        if idb.get(MADE_KEY) == name and getattr(idb, "library", None) is None and is_lixel_made(idb):
            return idb
    return None


def named_as_a_copy(idb) -> bool:
    """Whether ``idb`` carries Lixel's mark under a name Blender gives a copy of the datablock Lixel made ("Lixel
    Debug.001" of "Lixel Debug"): Blender's copy, made with a copy of its scene (Scene > New > Full Copy) or by the
    user's Shift+D. Only where the scene's own settings point at it is it the scene copy's (``ui.nodes``)."""
    made = idb.get(NAME_KEY) if MADE_KEY in idb.keys() else None
    if not isinstance(made, str) or made == idb.name:
        return False
    base = made.rstrip("0123456789")[:-1] if re.search(r"\.\d{3,}$", made) else made
    return re.fullmatch(re.escape(base) + r"\.\d{3,}", idb.name) is not None


def mark_made(idb, name: str):
    """Mark ``idb`` as made by Lixel under ``name``; returns it."""
    idb[MADE_KEY] = name
    idb[NAME_KEY] = idb.name
    return idb


def lixel_datablock(datablocks, name: str, *new_args):
    """Lixel's datablock ``name`` in ``datablocks``: the one it made before, or a
    new one (``datablocks.new(name, *new_args)``, which Blender renames when a
    user's datablock has the name), marked. Returns (datablock, made_now)."""
    idb = find_made(datablocks, name)
    if idb is not None:
        return idb, False
    return mark_made(datablocks.new(name, *new_args), name), True
