"""Light Linking and Shadow Linking of the light Lixel renders (Object properties > Shading, Blender 4.0+), as
per-instance masks over an :class:`~.instances.InstanceSet`.

A light's ``light_linking.receiver_collection`` says which objects it lights, its ``blocker_collection`` which
objects cast its shadows. Each object or child collection in such a collection is Included or Excluded
(``collection.collection_objects[i]`` / ``collection_children[i]``'s ``light_linking.link_state``, parallel to
``collection.objects`` / ``children``). Measured with Cycles (CPU) in 4.2.23 and 5.0.1, both the same:

* with only Excluded entries every object but those is lit / casts; with any Included entry only the Included ones
  are (Excluded entries beside them change nothing): Blender's documented rule;
* a child collection's state is that of every object in it (at any depth);
* a collection instance's objects are in the collection if their instancer is, or if they are themselves;
  geometry-nodes instances only if their instancer is (the instanced object's own entry is ignored): see
  :func:`.instances.linkers_of`, which records who decides for each instance.

Where the readers recorded no ``linkers`` (no light in the scene has linking) there is nothing to follow.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass(frozen=True)
class LightLinks:
    """What a light's linking leaves of each instance: ``lit[i]`` whether the light lights instance ``i``,
    ``blocks[i]`` whether it casts the light's shadow; None where the light has no such collection (all)."""

    lit: Optional[np.ndarray] = None
    blocks: Optional[np.ndarray] = None


def link_states(collection) -> dict[int, str]:
    """``{original object pointer: "INCLUDE" | "EXCLUDE"}`` for every object in ``collection``: an object's own
    entry, else the state of the child collection (at any depth) it is in; the first one met wins."""
    states: dict[int, str] = {}

    def add(coll, inherited: Optional[str]) -> None:
        for ob, entry in zip(coll.objects, coll.collection_objects):
            states.setdefault(ob.as_pointer(), inherited or entry.light_linking.link_state)
        for child, entry in zip(coll.children, coll.collection_children):
            add(child, inherited or entry.light_linking.link_state)

    add(collection, None)
    return states


def members(collection, linkers: np.ndarray) -> np.ndarray:
    """Whether each instance (its ``linkers`` rows: (instancer, own object) pointers, 0 for none) counts as in
    ``collection`` for linking: Included, or with no Included entry at all, not Excluded. The instance's own
    object's entry is read first, then its instancer's."""
    states = link_states(collection)
    include = "INCLUDE" in states.values()
    rows, inverse = np.unique(linkers, axis=0, return_inverse=True)     # (few deciders, many instances)
    state = [states.get(own) or states.get(parent) for parent, own in rows.tolist()]
    member = np.array([(s == "INCLUDE") if include else (s != "EXCLUDE") for s in state], dtype=bool)
    return member[inverse.reshape(-1)]


def _collections(light_obj) -> tuple:
    linking = getattr(light_obj, "light_linking", None)
    return getattr(linking, "receiver_collection", None), getattr(linking, "blocker_collection", None)


def linking_note(light_obj, instances) -> Optional[str]:
    """A warning where ``light_obj`` has linking that :func:`light_links` cannot follow: the readers recorded no
    ``linkers`` because no light object of the scene has linking (the light is itself an instance, say of a
    linked collection, which ``instances.light_linked`` does not look into)."""
    receivers, blockers = _collections(light_obj)
    if (receivers is None and blockers is None) or len(instances.linkers) == len(instances):
        return None
    what = " and ".join(f"{kind} to collection '{c.name}'" for kind, c in
                        (("Light Linking", receivers), ("Shadow Linking", blockers)) if c is not None)
    return (f"Light '{light_obj.name}' has {what} but is an instance (of a collection instance): Lixel does not "
            f"follow it and lights and shadows every object; make it a real object (Object > Apply > Make "
            f"Instances Real) to have its linking followed")


def light_links(light_obj, instances) -> LightLinks:
    """The masks of ``light_obj``'s Light Linking (``lit``) and Shadow Linking (``blocks``) over ``instances``;
    none where it has no such collection (nothing to follow: a frame draws as without linking), or where the
    readers recorded no ``linkers`` (see :func:`linking_note`)."""
    receivers, blockers = _collections(light_obj)
    if (receivers is None and blockers is None) or len(instances.linkers) != len(instances):
        return LightLinks()
    return LightLinks(lit=None if receivers is None else members(receivers, instances.linkers),
                      blocks=None if blockers is None else members(blockers, instances.linkers))
