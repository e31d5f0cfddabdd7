"""The one guard at every Lixel entry point: operators, the render engine, draw
callbacks, app handlers and timers, the background scripts (and, in its own
plain-Python way, the CLI in ``addon/cli``).

A :class:`WarpError` already carries a message for the user (it names the
object and says what to do). Anything else that escapes is a bug in Lixel: the
user gets one line saying what Lixel was doing, and the full traceback goes to
the log at debug level, never to the user. ``LIXEL_DEBUG=1`` in the environment
shows the debug log on stderr.

No bpy here: the guard is plain Python, usable by every layer above the math.
"""
from __future__ import annotations

import functools
import logging
import os

from .warp.types import WarpError

ROOT_LOGGER = (__package__ or "").rsplit(".addon", 1)[0] or "lixel"
log = logging.getLogger(__name__)

if os.environ.get("LIXEL_DEBUG"):
    _root = logging.getLogger(ROOT_LOGGER)
    _root.setLevel(logging.DEBUG)
    if not _root.handlers:
        _root.addHandler(logging.StreamHandler())


def user_message(exc: BaseException, doing: str) -> str:
    """What the user reads about ``exc``, raised while ``doing`` (e.g. "rendering
    scene 'Scene'"). A WarpError's own message; for anything else one line, and
    the traceback to the log at debug level."""
    if isinstance(exc, WarpError):
        return str(exc)
    log.debug("Lixel: unexpected error while %s", doing, exc_info=exc)
    detail = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return (f"unexpected error while {doing} ({type(exc).__name__}{': ' + detail if detail else ''}); "
            f"this is a bug in Lixel, please report it (run with LIXEL_DEBUG=1 for the traceback)")


def _scene_name(context) -> str:
    scene = getattr(context, "scene", None)
    return f" in scene '{scene.name}'" if scene is not None else ""


def guarded_operator(method):
    """Decorate an operator's ``execute``/``invoke``: any exception becomes an
    ERROR report naming the operator and the scene, and the operator returns
    CANCELLED (Blender then shows no traceback and pushes no undo step)."""
    @functools.wraps(method)
    def guarded(self, context, *args):
        try:
            return method(self, context, *args)
        except Exception as exc:  # noqa: BLE001 - the entry point's guard
            self.report({"ERROR"}, f"Lixel: {user_message(exc, f'running {self.bl_label!r}{_scene_name(context)}')}")
            return {"CANCELLED"}
    return guarded


_said: set = set()


def _quietly(fn, args, kw, doing: str, default):
    try:
        return fn(*args, **kw)
    except Exception as exc:  # noqa: BLE001 - never raise into Blender's loops
        msg = user_message(exc, doing)
        if msg not in _said:
            _said.add(msg)
            log.warning("Lixel: %s", msg)
        return default


def guarded_callback(doing: str, default=None):
    """Decorate a draw callback, app handler or timer: any exception is logged
    as one warning line (once per distinct message, so a draw loop does not
    flood the console), its traceback at debug level, and ``default`` is
    returned (e.g. a timer's "do not run again")."""
    def wrap(fn):
        @functools.wraps(fn)
        def guarded(*args, **kw):
            return _quietly(fn, args, kw, doing, default)
        return guarded
    return wrap


def guarded_draw(doing: str):
    """:func:`guarded_callback` for a UI class's ``draw(self, context)`` (Blender
    checks that the function takes exactly two arguments)."""
    def wrap(draw):
        @functools.wraps(draw)
        def guarded(self, context):
            return _quietly(draw, (self, context), {}, doing, None)
        return guarded
    return wrap
