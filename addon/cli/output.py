"""The warp core's results as JSON data: what ``python -m addon.warp`` prints, the
export operator writes and the scripts save."""
from __future__ import annotations

import contextlib
import math
import os
import re
import stat
import tempfile
from typing import Any

import numpy as np

from ..warp.diagnostics import Diagnostics
from ..warp.types import ShadowMap, ShadowSetup


def write_text(path: str, text: str) -> None:
    """Write ``text`` (UTF-8) to the file ``path`` whole or not at all (:func:`replacing`). OSError naming ``path``
    where it cannot be written."""
    with replacing(path) as temporary, open(temporary, "w", encoding="utf-8") as fh:
        fh.write(text)


@contextlib.contextmanager
def replacing(path: str):
    """A file to write instead of ``path``, beside it, renamed over it once the block ends without an exception,
    with the permissions ``path`` had (a new file: the umask's); removed where the block fails. So a write that fails
    part-way (a full disk) leaves the file that was there as it was and no half-written one: ``open(path, "w")``
    emptied the user's file first. A symbolic link's target is the file replaced; a path that is not a plain file (a
    device, a pipe) is written directly. An OSError is raised naming ``path``, never the temporary file."""
    target = os.path.realpath(path)
    if os.path.exists(target) and not os.path.isfile(target):
        yield target
        return
    mode = stat.S_IMODE(os.stat(target).st_mode) if os.path.exists(target) else 0o666 & ~_umask()
    base, ending = os.path.splitext(os.path.basename(target))
    try:
        fd, temporary = tempfile.mkstemp(prefix=f".{base}.", suffix=f".part{ending}", dir=os.path.dirname(target))
        os.close(fd)
    except OSError as exc:   # named as the file asked for, not the temporary one
        raise OSError(exc.errno, exc.strerror, path) from None
    try:
        yield temporary
        os.chmod(temporary, mode)
        os.replace(temporary, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        if isinstance(exc, OSError):
            raise OSError(exc.errno, exc.strerror, path) from None
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def setup_json(setup: ShadowSetup) -> dict:
    """``{"maps": [...], "diagnostics": {...}}``."""
    return {"maps": [map_json(m) for m in setup.maps], "diagnostics": diagnostics_json(setup.diagnostics)}


def empty_body_json(method: str, why: str) -> dict:
    """A setup's JSON where nothing the camera sees can be shadowed: no maps, ``diagnostics.empty_body`` says why."""
    return {"maps": [], "diagnostics": {"method": method, "empty_body": why, "fallbacks": []}}


def map_json(m: ShadowMap) -> dict:
    """A map's matrix, size, depth test and role, and what else it carries."""
    out: dict[str, Any] = {"matrix": m.matrix.tolist(), "size": [int(m.size[0]), int(m.size[1])],
                           "depth_test": m.depth_test, "role": m.role}
    if m.view_depth_range is not None:
        out["view_depth_range"] = [float(v) for v in m.view_depth_range]
    if m.region is not None:
        r = m.region
        out["region"] = {"normal": r.normal.tolist(), "offset": float(r.offset),
                         "polygon": np.asarray(r.polygon).tolist(), "tolerance": float(r.tolerance)}
    if m.depth_row is not None:
        out["depth_row"] = np.asarray(m.depth_row).tolist()
    if m.blend_band > 0:
        out["blend_band"] = float(m.blend_band)
    return out


RECEIVER_BOX = re.compile(r"\breceiver box (\d+)")
"""How the warp core's notes name a receiver (``plane_map``: the flattest box, the default plane's top): by its index
among the receivers B was built from (``body.culled.receivers``), a number no user can look up."""
PLANE_OPTION = re.compile(r"\bplanes\[(\d+)\]")
"""How they name a plane of interest given (``PlaneOfInterest.from_option``): by its index in ``WarpOptions.planes``,
the config's own name for it; the Lixel panel lists the planes by name."""


def name_in_notes(diagnostics: Diagnostics, pattern: re.Pattern, name) -> None:
    """Write each ``pattern`` (its group: an index i) in the diagnostics' notes and extra text as ``name(i)``."""
    def named(v):
        if isinstance(v, str):
            return pattern.sub(lambda m: name(int(m.group(1))), v)
        if isinstance(v, (list, dict)):
            return {k: named(x) for k, x in v.items()} if isinstance(v, dict) else [named(x) for x in v]
        return v
    diagnostics.fallbacks = [(what, named(why)) for what, why in diagnostics.fallbacks]
    diagnostics.extra = named(diagnostics.extra)


def name_receivers(diagnostics: Diagnostics, body, name) -> None:
    """Give each receiver the core's notes name by index (:data:`RECEIVER_BOX`) as ``name(k)``, k its index in the
    scene's receivers (``SceneBounds.receivers``): a config's ``boxes[k]``, an object of a Blender scene."""
    scene_index = np.flatnonzero(body.culled.receivers.mask)
    name_in_notes(diagnostics, RECEIVER_BOX,
                  lambda i: name(int(scene_index[i])) if i < len(scene_index) else f"receiver box {i}")


def diagnostics_json(d: Diagnostics) -> dict:
    """The diagnostics, angles in degrees, every value read."""
    out = {
        "method": d.method,
        "theta_deg": None if d.theta is None else math.degrees(d.theta),
        "gamma_deg": None if d.gamma is None else math.degrees(d.gamma),
        "n_opt": d.n_opt,
        "lambda": d.lam,
        "body_vertices": plain(d.body_vertices),
        "warp_frustum_corners": plain(d.warp_frustum_corners),
        "fallbacks": [{"what": w, "reason": r} for w, r in d.fallbacks],
    }
    out.update(plain(d.extra))
    return out


def plain(v):
    """``v`` as JSON data (arrays and numpy scalars as lists and numbers)."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v
