"""The JSON config of ``python -m addon.warp`` -> the warp core's plain inputs.

    {"camera": {"matrix_world": 4x4 row-major, "fov_y_deg": 60, "aspect": 1.7778,
                "near": 0.1, "far": 70, "resolution": [1280, 720]},
     "light":  {"type": "SUN"|"POINT"|"SPOT", "direction": [x,y,z], "position": [x,y,z],
                "spot_angle_deg": 90},
     "boxes":  [{"min": [x,y,z], "max": [x,y,z]}, ...],
     "shadow_map_size": 1024,                    (an int, or [w, h])
     "planes": [{"point": [...], "normal": [...],     (optional, plane_optimal)
                 "extent": [[x,y,z], ...]}],      (optional: the plane's convex outline, >= 3 points)
     "options": {...}}                            (optional WarpOptions fields)

An orthographic camera gives ``"orthographic": true`` and ``"ortho_height"``
instead of ``fov_y_deg``; the camera's scale is ignored, as Blender ignores it.
Every error names the field (``ConfigError``); a key the config format does not
know (``light.energy``), or one that does not apply (a sun's ``position``), is
an error too, never silently ignored.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..warp import MAX_COORDINATE
from ..warp.geometry import normalize, ortho_matrix
from ..warp.types import MAX_MAP_SIDE, Light, SceneBounds, View, WarpError, WarpOptions, clip_range_beyond_depth


class ConfigError(WarpError):
    """A malformed config; the message starts with the offending field."""


KEYS = {
    "": ("camera", "light", "boxes", "shadow_map_size", "planes", "options"),
    "camera": ("matrix_world", "fov_y_deg", "aspect", "near", "far", "resolution", "orthographic", "ortho_height"),
    "light": ("type", "name", "direction", "position", "spot_angle_deg"),
    "box": ("min", "max"),
    "plane": ("point", "normal", "extent"),
}
"""The keys each object of the config may have."""
LIGHT_KEYS = {"SUN": ("direction",), "POINT": ("position",), "SPOT": ("direction", "position", "spot_angle_deg")}
"""The keys each light type uses besides ``type`` and ``name``."""
ASPECT_RANGE = (1e-6, 1e6)
AXIS_RANGE = (1e-6, 1e6)
"""Lengths a camera matrix's axes may have: a scaled camera is taken unscaled, as Blender's renderers take it
(``addon.scene.describe.unscaled_camera_matrix``), a degenerate one is refused."""
FRUSTUM_ANGLE_DEGREES = (10.0, 170.0)
"""The Max Frustum Angle a user may set (``WarpOptions.max_frustum_angle``, in degrees), in the panel and the CLI
alike. Past 170° a point light's one perspective map spreads its texels thin at its centre, tan(half the angle)
times a 90° cube face's (11.4 at 170°, 1,146 at 179.9°): cube faces serve such a light better. Below 10° nearly
every point light takes cube faces, each 90° wide, wider than the limit asked for."""
PLANE_BUDGET = (0.01, 1.0)
"""The Plane Budget a user may set (``WarpOptions.plane_budget``, the most of the texel budget plane_optimal's plane
maps may take), in the panel and the CLI alike. Below 1 % a 1024² budget leaves the planes about 10,000 texels, a
100² map for what one lixel per pixel needs: a plane map that small helps nothing, and 1e-12 left none at all."""
ROUNDED_AXIS = 1e-6
"""A camera axis this close to unit length is a rotation written to 6 digits (the examples), taken as given."""
MAX_PROJECTION_CONDITION = 1e12
"""A projection beyond this condition number (a 1e-300° field of view, a 1e-300 clip
start) cannot be inverted in float64 to the frustum the core clips with. Clip
ranges of 1:1e15 from a 1e-6 start stay far below it (about 1e6)."""


def _only_known(obj, path: str, kind: str) -> None:
    """ConfigError naming the first key of ``obj`` that the format does not know."""
    if not isinstance(obj, dict):
        return
    known = KEYS[kind]
    for key in obj:
        if key not in known:
            where = f"{path}.{key}" if path else str(key)
            raise ConfigError(f"{where}: unknown key; known: {', '.join(known)}")


def _get(obj: dict, key: str, path: str, default: Any = ...):
    if not isinstance(obj, dict):
        raise ConfigError(f"{path}: must be an object")
    if key not in obj:
        if default is ...:
            raise ConfigError(f"{path}.{key}: missing" if path else f"{key}: missing")
        return default
    return obj[key]


def _number(value, field: str, *, positive=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{field}: must be a finite number (got {value!r})")
    if positive and value <= 0:
        raise ConfigError(f"{field}: must be positive (got {value!r})")
    return float(value)


def _vector(value, field: str, n: int = 3, coordinates: bool = False) -> np.ndarray:
    """``n`` finite numbers; ``coordinates``: within the core's ±MAX_COORDINATE."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: must be a list of {n} numbers") from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{field}: must be a list of {n} finite numbers (got {value!r})")
    if coordinates and float(np.abs(a).max()) > MAX_COORDINATE:
        raise ConfigError(f"{field}: coordinates must be within ±{MAX_COORDINATE:.0e} (got {value!r})")
    return a


def _matrix(value, field: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: must be a 4x4 list of numbers") from None
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{field}: must be a 4x4 list of finite numbers")
    if not np.array_equal(a[3], [0.0, 0.0, 0.0, 1.0]):
        raise ConfigError(f"{field}: the last row must be [0, 0, 0, 1] (an affine transform)")
    if float(np.abs(a[:3, 3]).max()) > MAX_COORDINATE:
        raise ConfigError(f"{field}: the position {a[:3, 3].tolist()} is beyond ±{MAX_COORDINATE:.0e}")
    scale = float(np.abs(a[:3, :3]).max())
    if scale == 0 or abs(np.linalg.det(a[:3, :3] / scale)) < 1e-12:
        raise ConfigError(f"{field}: the rotation part is singular")
    lengths = np.linalg.norm(a[:3, :3], axis=0)
    if not (AXIS_RANGE[0] <= lengths.min() and lengths.max() <= AXIS_RANGE[1]):
        raise ConfigError(f"{field}: the axes' lengths must be between {AXIS_RANGE[0]:g} and {AXIS_RANGE[1]:g} "
                          f"(got {', '.join(f'{v:.3g}' for v in lengths)})")
    if np.any(np.abs(lengths - 1.0) > ROUNDED_AXIS):   # eye depths, clip range and lens are lengths, not in scales
        a[:3, :3] /= lengths
    return a


def _size(value, field: str, unit: str = "texels") -> tuple[int, int]:
    if isinstance(value, bool):
        raise ConfigError(f"{field}: must be an int or [w, h]")
    if isinstance(value, int):
        w = h = value
    elif isinstance(value, (list, tuple)) and len(value) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        w, h = value
    else:
        raise ConfigError(f"{field}: must be an int or [w, h] of ints (got {value!r})")
    if not (1 <= w <= MAX_MAP_SIDE and 1 <= h <= MAX_MAP_SIDE):
        raise ConfigError(f"{field}: must be between 1 and {MAX_MAP_SIDE} {unit} per side (got {value!r})")
    return int(w), int(h)


def parse_view(cam: dict) -> View:
    _only_known(cam, "camera", "camera")
    m = _matrix(_get(cam, "matrix_world", "camera"), "camera.matrix_world")
    near = _number(_get(cam, "near", "camera"), "camera.near", positive=True)
    far = _number(_get(cam, "far", "camera"), "camera.far", positive=True)
    if far <= near:
        raise ConfigError(f"camera.far: must be greater than camera.near ({far} <= {near})")
    res = _size(_get(cam, "resolution", "camera", [1920, 1080]), "camera.resolution", "pixels")
    aspect = _number(_get(cam, "aspect", "camera", res[0] / res[1]), "camera.aspect", positive=True)
    if not ASPECT_RANGE[0] <= aspect <= ASPECT_RANGE[1]:
        raise ConfigError(f"camera.aspect: must be between {ASPECT_RANGE[0]:g} and {ASPECT_RANGE[1]:g} (got {aspect!r})")
    ortho = _get(cam, "orthographic", "camera", False)
    if not isinstance(ortho, bool):
        raise ConfigError(f"camera.orthographic: must be true or false (got {ortho!r})")
    if why := clip_range_beyond_depth(near, far, ortho):      # (the Blender path's rule: addon.scene.describe)
        raise ConfigError(f"camera.far: the camera {why}: raise camera.near or lower camera.far")
    unused, wanted = ("fov_y_deg", "ortho_height") if ortho else ("ortho_height", "fov_y_deg")
    if unused in cam:
        raise ConfigError(f"camera.{unused}: a{'n orthographic' if ortho else ' perspective'} camera does not take "
                          f"it; give camera.{wanted} instead")
    try:
        if ortho:
            h = _number(_get(cam, "ortho_height", "camera"), "camera.ortho_height", positive=True)
            view = View(m, ortho_matrix(-h * aspect / 2, h * aspect / 2, -h / 2, h / 2, near, far), near, far, res,
                        orthographic=True)
        else:
            fov = _number(_get(cam, "fov_y_deg", "camera"), "camera.fov_y_deg", positive=True)
            if fov >= 180:
                raise ConfigError(f"camera.fov_y_deg: must be below 180 (got {fov})")
            view = View.perspective(m, math.radians(fov), aspect, near, far, res)
    except ConfigError:
        raise
    except WarpError as exc:
        raise ConfigError(f"camera: {exc}") from None
    with np.errstate(all="ignore"):
        cond = float(np.linalg.cond(view.projection)) if np.all(np.isfinite(view.projection)) else math.inf
    if not cond < MAX_PROJECTION_CONDITION:
        lens = "ortho_height" if ortho else "fov_y_deg"
        raise ConfigError(f"camera: {lens}, aspect, near and far give a projection too ill-conditioned for floating "
                          f"point (condition number {cond:.3g}); use less extreme values")
    return view


def parse_light(light: dict) -> Light:
    _only_known(light, "light", "light")
    kind = _get(light, "type", "light")
    if kind not in ("SUN", "POINT", "SPOT"):
        raise ConfigError(f"light.type: must be SUN, POINT or SPOT (got {kind!r})")
    for key in light:
        if key not in ("type", "name") + LIGHT_KEYS[kind]:
            raise ConfigError(f"light.{key}: a {kind} light has no {key}; it takes "
                              f"{', '.join(LIGHT_KEYS[kind])} (and name)")
    name = light.get("name", "light")
    if not isinstance(name, str) or not name.strip():       # (the messages name the light by it)
        raise ConfigError(f"light.name: must be a non-empty string (got {name!r})")
    kw: dict[str, Any] = {"type": kind, "name": name}
    if kind in ("SUN", "SPOT"):
        d = _vector(_get(light, "direction", "light"), "light.direction")
        try:
            normalize(d)                                # (the core's: [1e308, 0, 0] is a direction too)
        except ValueError:
            raise ConfigError("light.direction: must be a non-zero vector") from None
        kw["direction"] = d
    if kind in ("POINT", "SPOT"):
        kw["position"] = _vector(_get(light, "position", "light"), "light.position", coordinates=True)
    if kind == "SPOT":
        angle = _number(_get(light, "spot_angle_deg", "light"), "light.spot_angle_deg", positive=True)
        if angle >= 180:
            raise ConfigError(f"light.spot_angle_deg: must be below 180 (got {angle})")
        kw["spot_angle"] = math.radians(angle)
    return Light(**kw)


def _entries(value, field: str, kind: str, needs: tuple):
    """(``field[i]``, entry) for each ``kind`` object (``KEYS``, ``needs`` those) of the list ``value``, or ConfigError."""
    if not isinstance(value, list):
        example = ", ".join(f'"{k}": [...]' for k in needs)
        raise ConfigError(f"{field}: must be a list of {{{example}}}")
    for i, entry in enumerate(value):
        _only_known(entry, f"{field}[{i}]", kind)
        yield f"{field}[{i}]", entry


def parse_boxes(boxes) -> SceneBounds:
    out = []
    for at, b in _entries(boxes, "boxes", "box", ("min", "max")):
        lo = _vector(_get(b, "min", at), f"{at}.min", coordinates=True)
        hi = _vector(_get(b, "max", at), f"{at}.max", coordinates=True)
        if np.any(lo > hi):
            raise ConfigError(f"{at}: min must not exceed max")
        out.append([lo, hi])
    return SceneBounds.from_boxes(np.asarray(out, dtype=np.float64).reshape(-1, 2, 3))


def parse_planes(planes) -> tuple:
    out = []
    for at, p in _entries(planes, "planes", "plane", ("point", "normal")):
        point = _vector(_get(p, "point", at), f"{at}.point", coordinates=True)
        normal = _vector(_get(p, "normal", at), f"{at}.normal")
        try:        # (the core's normalize, as for light.direction: [0, 0, 1e-300] is a direction too)
            plane = (point, normalize(normal))
        except ValueError:
            raise ConfigError(f"{at}.normal: must not be zero") from None
        if "extent" in p:  # what the sidebar's Planes From Selection keeps: the map covers only that outline
            plane += (_extent(p["extent"], f"{at}.extent", plane[1]),)
        out.append(plane)
    return tuple(out)


def _extent(value, field: str, normal: np.ndarray) -> np.ndarray:
    """A plane's outline: at least 3 points [x, y, z] (projected onto the plane by ``PlaneOfInterest.through``)
    spanning an area there; points on one line would leave the plane no part to map, reported as "no visible
    part"."""
    if not isinstance(value, list) or len(value) < 3:
        raise ConfigError(f"{field}: must be a list of at least 3 points [x, y, z] (the plane's convex outline)")
    points = np.array([_vector(v, f"{field}[{k}]", coordinates=True) for k, v in enumerate(value)])
    on_plane = points - points.mean(axis=0)
    on_plane -= np.outer(on_plane @ normal, normal)
    spread = np.linalg.svd(on_plane, compute_uv=False)
    if spread[1] <= 1e-9 * max(spread[0], 1e-300):
        raise ConfigError(f"{field}: the points lie on one line or point of the plane, an outline with no area: "
                          f"give the corners of the plane's outline")
    return points


def _option(key: str, value, annotation: str):
    """Check one ``options`` entry against its WarpOptions field type."""
    field = f"options.{key}"
    if key == "max_frustum_angle":
        deg, (low, high) = _number(value, field), FRUSTUM_ANGLE_DEGREES
        if not low <= deg <= high:      # (the Lixel panel's range too)
            raise ConfigError(f"{field}: must be from {low:g} to {high:g} degrees, as in the Lixel panel; wider "
                              f"lights take cube faces (got {value!r})")
        return math.radians(deg)
    if key == "plane_budget":
        share, (low, high) = _number(value, field), PLANE_BUDGET
        if not low <= share <= high:    # (the Lixel panel's range too)
            raise ConfigError(f"{field}: must be from {low:g} to {high:g}, as in the Lixel panel: the share of the "
                              f"texel budget the plane maps may take (got {value!r})")
        return share
    optional = annotation.startswith("Optional[")
    kind = annotation[len("Optional["):-1] if optional else annotation
    if value is None:
        if optional:
            return None
        raise ConfigError(f"{field}: must not be null")
    if kind == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{field}: must be true or false (got {value!r})")
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{field}: must be a string (got {value!r})")
        return value
    if kind == "float":
        return _number(value, field, positive=key == "lam")      # (a forced λ must be positive)
    if kind == "tuple[float, float]":
        a = _vector(value, field, 2)
        if not 0 <= a[0] < a[1]:                                 # (the Lixel panel's Visible Range rule)
            raise ConfigError(f"{field}: must be [near, far] eye depths with 0 <= near < far (got {value!r})")
        return (float(a[0]), float(a[1]))
    return tuple(value) if isinstance(value, list) else value


def parse_options(config: dict) -> WarpOptions:
    kw: dict[str, Any] = {}
    if "shadow_map_size" in config:
        kw["shadow_map_size"] = _size(config["shadow_map_size"], "shadow_map_size")
    if "planes" in config:
        kw["planes"] = parse_planes(config["planes"])
    extra = config.get("options", {})
    if not isinstance(extra, dict):
        raise ConfigError("options: must be an object")
    fields = {f.name: str(f.type) for f in dataclasses.fields(WarpOptions)}
    names = set(fields) - {"shadow_map_size", "planes"}
    for key, value in extra.items():
        if key in ("shadow_map_size", "planes"):
            raise ConfigError(f"options.{key}: give {key} at the config's top level, beside \"options\"")
        if key not in names:
            raise ConfigError(f"options.{key}: unknown option; known: {', '.join(sorted(names))}")
        kw[key] = _option(key, value, fields[key])
        try:
            WarpOptions(**{key: kw[key]})
        except (WarpError, TypeError, ValueError) as exc:
            raise ConfigError(f"options.{key}: {exc}") from None
    try:
        return WarpOptions(**kw)
    except (WarpError, TypeError, ValueError) as exc:
        raise ConfigError(f"options: {exc}") from None


def parse_config(config: dict) -> tuple[View, Light, SceneBounds, WarpOptions]:
    if not isinstance(config, dict):
        raise ConfigError("config: must be a JSON object")
    _only_known(config, "", "")
    view = parse_view(_get(config, "camera", ""))
    try:
        light = parse_light(_get(config, "light", ""))
    except ConfigError:
        raise
    except WarpError as exc:
        raise ConfigError(f"light: {exc}") from None
    scene = parse_boxes(_get(config, "boxes", ""))
    options = parse_options(config)
    if options.visible_depth_range is not None:
        near, far = options.visible_depth_range
        if not view.sees_depths(near, far):    # (within the clip range, a part is taken: the methods clamp)
            raise ConfigError(f"options.visible_depth_range: [{near:g}, {far:g}] lies wholly outside the camera's "
                              f"clip range [{view.near:g}, {view.far:g}] (camera.near, camera.far), so the camera "
                              f"sees nothing there: give eye depths that overlap the clip range, or drop the option")
    return view, light, scene, options
