"""A shared catalogue of named hard configurations for the warp core.

    from hard_cases import HARD_CASES, EMPTY_CASES, case   # in tests/warp (pytest puts it on sys.path)
    view, light, scene = HARD_CASES["theta_equals_phi"]

``HARD_CASES`` maps a name to ``(View, Light, SceneBounds)``. The cases in
``EMPTY_CASES`` have an empty intersection body B (``intersection_body`` must
raise ``EmptyBodyError``); every other case has a non-empty B. ``DESCRIPTIONS``
says in one line what each case is and why it is hard.

φ is half the vertical field of view and θ the angle between the light and
view directions (GMNPR's convention); the θ = φ cases rotate the light away
from the view direction inside the camera's vertical plane by exactly φ (and
φ ± 1e-9).
"""
from __future__ import annotations

import math

import numpy as np

from addon.warp import Light, SceneBounds, View
from addon.warp.frame import image_up_blend
from addon.warp.geometry import look_along, ortho_matrix

FOV_DEG = 60.0
PHI = math.radians(FOV_DEG) / 2
"""Half the vertical field of view of the default camera."""


def camera(pos, target=None, *, forward=None, fov=FOV_DEG, near=0.1, far=100.0, up=(0.0, 0.0, 1.0),
           res=(1280, 720)) -> View:
    """A perspective camera at ``pos`` looking at ``target`` (or along ``forward``)."""
    pos = np.asarray(pos, dtype=float)
    fwd = np.asarray(forward, dtype=float) if forward is not None else np.asarray(target, dtype=float) - pos
    c2w = np.linalg.inv(look_along(pos, fwd, up))
    return View.perspective(c2w, math.radians(fov), res[0] / res[1], near, far, res)


def town(offset=(0.0, 0.0, 0.0), size=50.0, flat=False) -> SceneBounds:
    """A ground slab of half-size ``size`` and a grid of 1 x 1 x 3 m boxes (flat tiles when ``flat``)."""
    o = np.asarray(offset, dtype=float)
    boxes = [[[-size, -size, -0.1], [size, size, 0.0]]]
    top = 0.0 if flat else 3.0
    for x in range(-20, 21, 8):
        for y in range(-5, 36, 8):
            boxes.append([[x, y, 0.0], [x + 1, y + 1, top]])
    return SceneBounds.from_boxes(np.asarray(boxes, dtype=float) + o)


def huge_ground(view: View, half: float | None, reach: float = 400.0) -> SceneBounds:
    """:func:`town` with its ground ±``half`` m wide (a huge box standing for an endless floor), or for None its
    trimmed twin: the ground cut to the view frustum's bounding box grown by ``reach`` m, farther than a sun 1° high
    crosses the 3 m boxes (what can be seen, and what can shadow it)."""
    boxes, corners = town().receivers.copy(), view.corners()[:, :2]
    lo, hi = (corners.min(axis=0) - reach, corners.max(axis=0) + reach) if half is None else (-half, half)
    boxes[0, 0, :2], boxes[0, 1, :2] = lo, hi
    return SceneBounds.from_boxes(boxes)


def sun(direction) -> Light:
    return Light("SUN", direction=np.asarray(direction, dtype=float), name="Sun")


def point(position) -> Light:
    return Light("POINT", position=np.asarray(position, dtype=float), name="Lamp")


def spot(position, direction, angle) -> Light:
    return Light("SPOT", position=np.asarray(position, dtype=float), direction=np.asarray(direction, dtype=float),
                 spot_angle=angle, name="Spot")


def _rotated_towards_up(view: View, angle: float) -> np.ndarray:
    """The view direction rotated by ``angle`` towards the camera's down vector
    (inside the camera's vertical plane): θ = angle exactly."""
    return math.cos(angle) * view.direction - math.sin(angle) * view.up


def _street() -> View:
    return camera([0.0, -20.0, 5.0], [0.0, 10.0, 0.0])


def _build() -> tuple[dict, dict]:
    cases: dict[str, tuple[View, Light, SceneBounds]] = {}
    why: dict[str, str] = {}

    def add(name, view, light, scene, text):
        cases[name] = (view, light, scene)
        why[name] = text

    street = _street()
    scene = town()
    add("sun_parallel_to_view", street, sun(street.direction), scene,
        "sun travelling exactly along the view direction (γ = 0: LiSPSM's V_P vanishes)")
    add("sun_antiparallel_to_view", street, sun(-street.direction), scene,
        "sun shining straight into the camera (γ = π)")
    top = camera([3.0, 10.0, 40.0], forward=[0.0, 0.0, -1.0], up=(0.0, 1.0, 0.0))
    add("sun_parallel_top_down", top, sun([0.0, 0.0, -1.0]), scene,
        "camera looking straight down, sun straight down: both exactly along -Z")
    level = camera([0.0, -30.0, 1.7], forward=[0.0, 1.0, 0.0])
    add("sun_perpendicular_axis_aligned", level, sun([0.0, 0.0, -1.0]), scene,
        "camera looking along +Y, sun along -Z: exactly perpendicular, both axis-aligned")
    add("sun_perpendicular_axis_aligned_x", level, sun([1.0, 0.0, 0.0]), scene,
        "camera along +Y, sun along +X: perpendicular in the ground plane")
    for name, angle in (("theta_equals_phi", PHI), ("theta_phi_plus_1e-9", PHI + 1e-9),
                        ("theta_phi_minus_1e-9", PHI - 1e-9)):
        add(name, street, sun(_rotated_towards_up(street, angle)), scene,
            f"θ = φ{name[len('theta_phi'):].replace('_', ' ')} (GMNPR's critical angle)" if name != "theta_equals_phi"
            else "θ = φ exactly (GMNPR's critical angle, Eq. 8 switches there)")
    add("sun_behind_camera", street, sun(street.direction + np.array([0.0, 0.0, -0.8])), scene,
        "sun from behind the camera (γ < 90°)")
    elev = math.radians(1.0)
    add("sun_1deg_above_horizon", street, sun([0.3 * math.cos(elev), math.cos(elev), -math.sin(elev)]), scene,
        "a sun 1° above the horizon: B is stretched hundreds of metres along the light")
    add("near_1e-3_far_1e2", camera([0.0, -20.0, 1.7], [0.0, 10.0, 0.0], near=1e-3, far=1e2),
        sun([0.4, 0.3, -0.6]), scene, "near 1e-3, far 1e2 (f/n = 1e5)")
    add("near_0.1_far_1e4", camera([0.0, -20.0, 30.0], [0.0, 500.0, 0.0], near=0.1, far=1e4),
        sun([0.4, 0.3, -0.6]), town(size=6000.0), "near 0.1, far 1e4 over a 12 km ground")
    off = np.array([1e5, -1e5, 1e5])
    add("scene_offset_1e5", camera(off + [0.0, -20.0, 5.0], off + [0.0, 10.0, 0.0]), sun([0.4, 0.3, -0.6]),
        town(offset=off), "the whole configuration translated by (1e5, -1e5, 1e5)")
    add("point_light_offset_1e5", camera(off + [0.0, -20.0, 5.0], off + [0.0, 10.0, 0.0]), point(off + [5.0, 10.0, 20.0]),
        town(offset=off), "a point light with everything at 1e5")
    add("flat_scene", street, sun([0.4, 0.3, -0.6]), town(flat=True),
        "every box has zero height (B would be flat without the padding)")
    add("flat_scene_point", street, point([0.0, 5.0, 10.0]), town(flat=True),
        "a flat scene under a point light")
    add("empty_body", camera([0.0, -20.0, 5.0], forward=[0.0, 0.3, 1.0]), sun([0.4, 0.3, -0.6]), scene,
        "the camera looks at the sky: no receiver in view, B is empty")
    add("empty_body_spot_away", street, spot([0.0, -25.0, 5.0], [0.0, -1.0, 0.0], math.radians(30.0)), scene,
        "a spot pointing away from everything the camera sees")
    room = SceneBounds.from_boxes(np.array([[[-10.0, -10.0, 0.0], [10.0, 10.0, 5.0]],
                                            [[-1.0, 2.0, 0.0], [1.0, 3.0, 1.0]]]))
    add("camera_inside_scene_box", camera([0.0, -5.0, 1.7], [0.0, 5.0, 0.5]), sun([0.4, 0.3, -0.6]), room,
        "the camera stands inside a receiver box (a room)")
    add("camera_inside_scene_box_point", camera([0.0, -5.0, 1.7], [0.0, 5.0, 0.5]), point([0.0, 0.0, 4.0]), room,
        "a lamp and the camera inside one receiver box: the light is inside B")
    add("camera_1cm_above_ground", camera([0.0, -20.0, 0.01], forward=[0.0, 1.0, -0.001], near=0.01),
        sun([0.4, 0.3, -0.6]), scene, "the eye 1 cm above the ground, looking almost level")
    cam = street
    side = np.cross(cam.direction, cam.up)
    add("point_light_in_camera_plane", cam, point(cam.position + 8.0 * side + 3.0 * cam.up), scene,
        "a point light exactly in the camera plane (eye depth 0: PSM's light becomes directional)")
    add("point_light_behind_camera", cam, point(cam.position - 6.0 * cam.direction + 4.0 * cam.up), scene,
        "a point light behind the camera (PSM's inverted light)")
    add("point_light_inside_view", cam, point([0.0, 8.0, 2.0]), scene,
        "a point light inside the view frustum among the boxes: B surrounds it, cube faces")
    add("point_light_high_above", cam, point([0.0, 10.0, 60.0]), scene,
        "a point light high above the scene: one perspective map")
    add("spot_at_camera", cam, spot(cam.position, cam.direction, math.radians(80.0)), scene,
        "a flashlight: a spot exactly at the eye along the view (PSM: the light at the eye is singular)")
    low = camera([0.0, 0.0, 1.0], forward=[1.0, 0.0, 0.0], fov=2 * math.degrees(math.atan(1 / 4.5107085)),
                 near=1.0, far=100.0)
    add("spot_at_eye_aimed_aside", low, spot(low.position, [1.0, 0.35, -0.3], math.radians(63.0)), scene,
        "a spot at the eye of a level camera, aimed 19° aside and 16° down (a spot at the eye aimed 45° aside "
        "once made psm jump under a 1e-8 move)")
    add("point_light_at_camera", cam, point(cam.position), scene,
        "a point light exactly at the eye (a headlamp)")
    add("point_light_near_camera", cam, point(cam.position + np.array([0.3, 0.0, 0.2])), scene,
        "a point light 36 cm from the eye")
    diag_half = math.atan(math.hypot(math.tan(PHI), math.tan(PHI) * 1280 / 720))
    add("spot_barely_contains_view", cam, spot(cam.position - 0.5 * cam.direction, cam.direction,
                                               2 * diag_half + math.radians(1.0)), scene,
        "a spot just behind the camera whose cone is 1° wider than the view's diagonal")
    add("spot_over_scene", cam, spot([-10.0, -10.0, 25.0], [0.4, 0.6, -1.0], math.radians(70.0)), scene,
        "an ordinary spot light above the scene")
    ortho = View(street.camera_to_world, ortho_matrix(-16.0, 16.0, -9.0, 9.0, 0.1, 100.0), 0.1, 100.0,
                 (1280, 720), orthographic=True)
    add("orthographic_camera", ortho, sun([0.4, 0.3, -0.6]), scene, "an orthographic camera (PSM has no perspective to warp)")
    ortho_top = View(np.linalg.inv(look_along([0.0, 10.0, 50.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0])),
                     ortho_matrix(-30.0, 30.0, -20.0, 20.0, 1.0, 100.0), 1.0, 100.0, (1280, 720), orthographic=True)
    add("orthographic_top_down_zenith", ortho_top, sun([0.0, 0.0, -1.0]), scene,
        "an orthographic top-down camera under a zenith sun")
    add("sun_on_horizon", street, sun([0.3, 1.0, 0.0]), scene, "a sun exactly on the horizon (rays parallel to the ground)")
    add("sun_from_below", street, sun([0.3, 0.2, 1.0]), scene, "light travelling upwards (from under the ground)")
    add("single_small_box", street, sun([0.4, 0.3, -0.6]), SceneBounds.from_boxes([[[-2.0, 8.0, 0.0], [2.0, 12.0, 2.0]]]),
        "the only box is 4 x 4 x 2 m in the middle of the view, nothing around it")
    add("huge_ground", street, sun([0.4, 0.3, -0.6]), SceneBounds.from_boxes([[[-1e6, -1e6, -1.0], [1e6, 1e6, 0.0]]]),
        "one 2000 km ground box")
    add("spot_narrow_5deg", street, spot([0.0, -60.0, 60.0], [0.0, 70.0, -60.0], math.radians(5.0)), scene,
        "a 5° spot from 90 m: B is a long thin cone")
    add("spot_179deg", street, spot([0.0, 5.0, 10.0], [0.0, 0.0, -1.0], math.radians(179.0)), scene,
        "a 179° spot (almost a half-space): cube faces")
    return cases, why


HARD_CASES, DESCRIPTIONS = _build()
EMPTY_CASES = frozenset({"empty_body", "empty_body_spot_away"})
NONEMPTY_CASES = tuple(n for n in HARD_CASES if n not in EMPTY_CASES)


def case(name: str) -> tuple[View, Light, SceneBounds]:
    return HARD_CASES[name]


def image_up_singularity(view_direction, view_up, light_direction) -> float:
    """How far ``frame.image_up`` is from its singular point: the length of its
    unnormalised blend (0 at the point, 1 outside the blend); within ε of it a
    turn δ of the camera turns the map by about δ / (ε sin 1°)."""
    return math.hypot(*image_up_blend(view_direction, view_up, light_direction))
