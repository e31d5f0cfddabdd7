"""Lixel: warped shadow maps for Blender (extension root).

Registration order is fixed here; unregistration runs in reverse. Each listed
module exposes ``register()`` and ``unregister()``.
"""
from __future__ import annotations

import importlib
import logging

log = logging.getLogger(__name__)

# properties first (everything else reads them), render engine last.
_MODULE_NAMES = (
    ".addon.ui.properties",
    ".addon.ui.preferences",
    ".operators",
    ".addon.ui.panel",
    ".addon.ui.overlays",
    ".addon.render.engine",
)


def _modules():
    mods = []
    for name in _MODULE_NAMES:
        try:
            mods.append(importlib.import_module(name, __package__))
        except ModuleNotFoundError as exc:  # a layer not built yet must not break the others
            if exc.name and exc.name.startswith(__package__ or "addon"):
                log.debug("Lixel: %s not available (%s)", name, exc)
                continue
            raise
    # TEMPORARY while the layers are being built: skip a package that has no register() yet.
    return [m for m in mods if hasattr(m, "register")]


def register():
    for mod in _modules():
        mod.register()


def unregister():
    for mod in reversed(_modules()):
        mod.unregister()
