"""Lixel: warped shadow maps for Blender (extension root).

Registration order is fixed here; unregistration runs in reverse. Each listed
module exposes ``register()`` and ``unregister()``.
"""
from __future__ import annotations

import importlib

# properties first (everything else reads them), render engine last.
_MODULE_NAMES = (
    ".addon.ui.properties",
    ".addon.ui.preferences",
    ".addon.ui.operators",
    ".addon.ui.panel",
    ".addon.ui.overlays",
    ".addon.render.engine",
)


def _modules():
    return [importlib.import_module(name, __package__) for name in _MODULE_NAMES]


def register():
    done = []
    try:
        for mod in _modules():
            mod.register()
            done.append(mod)
    except Exception:
        # leave nothing half-registered (Blender 4.2 crashes at exit on leftovers)
        for mod in reversed(done):
            mod.unregister()
        raise


def unregister():
    for mod in reversed(_modules()):
        mod.unregister()
