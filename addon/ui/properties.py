"""``scene.lixel``: Lixel's settings stored on the Scene, mirroring the plain
data of ``addon.settings`` (``LixelSettings``, ``ShadowSettings``) and
``addon.warp.types.WarpOptions``; ``to_settings()`` converts.

Defaults of a scene that has never been set up come from the add-on
preferences (``addon.ui.preferences``), applied by :func:`ensure_defaults`.
"""
import math
from dataclasses import replace

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, IntVectorProperty, PointerProperty, StringProperty)

from ..scene.units import length_text
from ..cli.config import FRUSTUM_ANGLE_DEGREES, PLANE_BUDGET
from ..settings import (BIAS_MODES, MAX_EYE_BLUR, MAX_MAP_SIZE, MDSM_SELECTIONS, MIN_MAP_SIZE, LixelSettings,
                        ShadowSettings)
from ..warp.types import WarpError, WarpOptions
from . import addon_preferences

# Methods named in docs/architecture.md, in the order the UI lists them.
DOCUMENTED_METHODS = ("uniform", "psm", "lispsm", "gmnpr", "glpr", "plane_optimal")
METHOD_LABELS = {
    "uniform": ("Uniform", "Orthographic/perspective light map fitted to B, no warp (reference)"),
    "psm": ("PSM", "Perspective shadow maps: the map is taken in the camera's post-perspective space "
                   "(Stamminger-Drettakis §3-4)"),
    "lispsm": ("LiSPSM", "Light-space perspective shadow maps with n_opt (Scherzer §4.4, Eq. 1-3)"),
    "gmnpr": ("GMNPR", "Generalized minimum-norm perspective reparameterisation, λ by Eq. 8 (Zhang et al.)"),
    "glpr": ("GLPR", "Generalized LiSPSM reparameterisation, λ by Eq. 9 (Zhang et al.)"),
    "plane_optimal": ("Plane optimal", "One map per plane of interest, exact for that plane, plus a fallback "
                                       "map (Chong-Gortler §2-3)"),
    "cascade": ("Cascade", "z-splits of the view, each with its own B and warp, placed by Lloyd's model "
                           "(Scherzer §3, PSSM)"),
}

LAMBDA_METHODS = ("gmnpr", "glpr")
N_OPT_METHODS = ("lispsm",)
PLANE_METHODS = ("plane_optimal",)
CASCADE_METHODS = ("cascade",)
CASCADE_WARP_ITEMS = (
    ("auto", "Auto", "Per split, the warp with the lowest predicted error (Lloyd's model)"),
    ("uniform", "Uniform", "Every split a uniform map fitted to its B"),
    ("psm", "PSM", "Every split a perspective shadow map (Stamminger-Drettakis)"),
    ("lispsm", "LiSPSM", "Every split a LiSPSM warp (Scherzer §4.4)"),
    ("gmnpr", "GMNPR", "Every split a GMNPR warp (Zhang et al. Eq. 8)"))


def available_methods() -> tuple[str, ...]:
    """Method names the warp core registers, documented ones first. Falls back
    to the documented names while the core is being built."""
    try:
        from ..warp.methods import METHODS
        names = tuple(METHODS)
    except ImportError:
        names = ()
    return DOCUMENTED_METHODS + tuple(n for n in names if n not in DOCUMENTED_METHODS)


def method_items():
    items = []
    for i, name in enumerate(available_methods()):
        label, desc = METHOD_LABELS.get(name, (name.replace("_", " ").title(), f"Warp method '{name}'"))
        items.append((name, label, desc, i))
    return items


def _light_poll(self, obj):
    return obj.type == "LIGHT"


PLANE_CORNERS = 8
"""Corners a plane of interest's extent keeps (a larger hull is enclosed: plane_map.enclosing_polygon)."""


class LixelPlane(bpy.types.PropertyGroup):
    """A plane of interest for plane_optimal (Chong-Gortler §3): a point on it, its normal and
    the convex extent of the faces it was taken from (its first ``corners`` rows; 0: unbounded)."""

    point: FloatVectorProperty(name="Point", subtype="TRANSLATION", size=3, default=(0.0, 0.0, 0.0))
    normal: FloatVectorProperty(name="Normal", subtype="DIRECTION", size=3, default=(0.0, 0.0, 1.0))
    source: StringProperty(name="Source", description="What the plane was taken from")
    extent: FloatVectorProperty(name="Extent", size=(PLANE_CORNERS, 3), default=[(0.0, 0.0, 0.0)] * PLANE_CORNERS,
                                description="The corners of the convex polygon the plane's shadow map covers")
    corners: IntProperty(name="Corners", default=0, min=0, max=PLANE_CORNERS,
                         description="How many extent corners are set (0: the plane is unbounded)")

    def label(self, index: int) -> str:
        """How the panel lists the plane (``index``: its place in the list)."""
        return self.source or f"Plane {index}"

    def extent_corners(self) -> tuple:
        return tuple(tuple(c) for c in self.extent[:self.corners])

    def set_extent(self, corners) -> None:
        corners = [tuple(map(float, c)) for c in corners][:PLANE_CORNERS]
        self.extent = corners + [(0.0, 0.0, 0.0)] * (PLANE_CORNERS - len(corners))
        self.corners = len(corners)


OVERLAYS = (
    ("show_body", "Intersection body B", "The intersection body B: translucent faces and edges (Scherzer §4.1)"),
    ("show_frusta", "View and light frusta", "The camera's view frustum and each shadow map's light frustum"),
    ("show_warp", "Warp frustum P", "The warp frustum P with its projection centre, V_P and B's middle vector "
                                    "(Scherzer §4.4)"),
    ("show_texels", "Texel grid", "A checker of shadow-map texel parity on the receivers, so texel sizes show"),
    ("show_footprint", "Footprint heatmap", "Shadow-map texel footprint per screen pixel on the receivers "
                                            "(Stamminger-Drettakis §1.1)"),
    ("show_map", "Shadow map", "The shadow map itself, picture-in-picture"),
    ("show_shadowed", "Shadowed scene", "The scene shaded with Lixel's shadows"),
)


class LixelSceneSettings(bpy.types.PropertyGroup):
    """Everything Lixel needs to compute and render shadows for this scene."""

    initialised: BoolProperty(
        name="Initialised", default=False, options={"HIDDEN"},
        description="The preference defaults have been applied to this scene")
    debug_collection: PointerProperty(
        name="Debug Collection", type=bpy.types.Collection, options={"HIDDEN"},
        description="The collection Lixel keeps this scene's debug objects in (a full copy of the scene points at "
                    "its copy)")
    light: PointerProperty(
        name="Light", type=bpy.types.Object, poll=_light_poll,
        description="The light that casts Lixel's shadows (empty: the active light, else the first sun)")
    method: EnumProperty(name="Method", items=method_items(), default="lispsm",
                         description="How the shadow map is parametrised")

    # WarpOptions
    shadow_map_size: IntVectorProperty(
        # no hard min/max: Blender would clamp a typed 0 or 65536 silently; warp_options refuses it by name
        name="Map Size", size=2, default=(2048, 2048), soft_min=MIN_MAP_SIZE, soft_max=8192,
        description=f"Shadow map texels (width, height); {MIN_MAP_SIZE} to {MAX_MAP_SIZE} per side. "
                    "Multi-map methods split this budget")
    focus: EnumProperty(
        name="Focus", default="visible",
        items=(("visible", "What Is Visible", "Fit the maps to what the camera sees: the render's depth pre-pass, "
                                              "or in the viewport a coarse ray cast against the objects' bounds "
                                              "(Scherzer §4.4, Lauritzen et al. 2011)"),
               ("view", "View Frustum", "Fit the maps to the whole view frustum (Scherzer §4.1; Lixel before 0.2)")),
        description="What B, and so every map, is fitted to")
    lambda_guard: EnumProperty(
        name="λ Guard", default="all",
        items=(("all", "Every Warp", "Keep LiSPSM's, GMNPR's and GLPR's warp no worse than the uniform map, at its worst "
                                     "and over the visible pixels (docs/papers.md)"),
               ("glpr", "GLPR Only", "Guard only GLPR, the over-strong warp GMNPR §3 warns of"),
               ("off", "Off", "Every warp's λ exactly as its paper gives it")),
        description="Raise a warp's λ where its own rule would make the shadows worse than the uniform map's")
    texel_snapping: BoolProperty(name="Texel Snapping", default=False,
                                 description="Snap the uniform map's window to whole texels so shadows do not crawl")
    delta_z: EnumProperty(
        name="n_opt Δz", default="body",
        items=(("body", "Body", "Δz is the extent of B along the view direction (Scherzer §4.4, Eq. 1)"),
               ("visible", "Visible", "Δz is the visible depth range (Scherzer §4.4, 'Δz from visibility')")),
        description="What Δz in n_opt = (z_n + √(z_n(z_n+Δz)))/sin γ measures (Scherzer Eq. 1)")
    use_visible_depth_range: BoolProperty(
        name="Custom Visible Range", default=False,
        description="Give the visible depth range by hand instead of taking it from the scene")
    visible_depth_range: FloatVectorProperty(
        name="Visible Range", size=2, default=(0.1, 100.0), min=0.0, subtype="NONE", unit="LENGTH",
        description="Near and far eye depth of what is visible (Δz = Visible, PSM's near plane, the cascade's splits)")
    middle_vector: BoolProperty(
        name="Middle Vector", default=False,
        description="Use B's middle vector as V_P instead of Eq. 3 (Scherzer §4.4)")
    linear_z: BoolProperty(name="Linear Z", default=WarpOptions().linear_z,
                           description="Linear depth distribution in the map (Scherzer §4.2)")
    use_lambda: BoolProperty(name="Override λ", default=False,
                             description="Force GMNPR's λ instead of computing it (Zhang et al. Eq. 8/9)")
    lam: FloatProperty(name="λ", default=0.5, min=0.0, soft_max=1.0, precision=4,
                       description="The reparameterisation's λ (Zhang et al. Eq. 2)")
    max_frustum_angle: FloatProperty(
        name="Max Frustum Angle", default=math.radians(120.0), min=math.radians(FRUSTUM_ANGLE_DEGREES[0]),
        max=math.radians(FRUSTUM_ANGLE_DEGREES[1]),
        subtype="ANGLE", description="Widest single perspective map for a point light; wider needs take cube faces")
    planes: CollectionProperty(type=LixelPlane, name="Planes of Interest")
    active_plane: IntProperty(name="Active Plane", default=0, min=0)
    plane_budget: FloatProperty(name="Plane Budget", default=0.75, min=PLANE_BUDGET[0], max=PLANE_BUDGET[1],
                                subtype="FACTOR",
                                description="The most of the texel budget the plane maps may take; they take only "
                                            "what one lixel per pixel needs, the fallback map gets the rest")
    plane_twist: EnumProperty(
        name="Plane Twist", default="auto",
        items=(("auto", "Auto", "Rotate a plane map's image when the budget forces fewer lixels than pixels and the "
                                "rotated rectangle is tighter (Chong-Gortler §2)"),
               ("on", "On", "Always fit the rotated (twisted) rectangle (Chong-Gortler §2)"),
               ("off", "Off", "Never rotate the plane map's image")))

    cascade_splits: IntProperty(name="Splits", default=4, min=1, max=8,
                                description="z-splits of the view's depth range, each with its own map (cascade)")
    cascade_warp: EnumProperty(name="Split Warp", default="auto", items=CASCADE_WARP_ITEMS,
                               description="Each split's warp (cascade)")
    cascade_lambda: FloatProperty(
        name="Split λ", default=0.5, min=0.0, max=1.0, subtype="FACTOR",
        description="The practical split scheme's blend of logarithmic (1) and uniform (0) splits (PSSM)")
    cascade_adaptive: BoolProperty(
        name="Adaptive Splits", default=True,
        description="Move the splits to minimise the largest predicted error (Lloyd's model)")
    cascade_stable: BoolProperty(
        name="Stable", default=False,
        description="Quantised split depths and texel-snapped uniform maps of the whole view, not only of what it "
                    "sees: no shimmer while the camera moves, for coarser shadow edges")
    cascade_budget: EnumProperty(
        name="Texel Budget", default="per_map",
        items=(("per_map", "Per Map", "Every split a map of the configured size (PSSM)"),
               ("shared", "Shared", "The configured size is the whole budget, shared by predicted error")),
        description="How the cascade's texels are shared between its maps")
    cascade_blend: FloatProperty(
        name="Blend Band", default=0.1, min=0.0, max=0.5, subtype="FACTOR",
        description="The band over which a split's shadow fades into the next one, as a part of the split")

    # ShadowSettings
    bias_mode: EnumProperty(
        name="Bias", default=ShadowSettings().bias_mode,
        items=(("NONE", "None", "No depth bias"),
               ("CONSTANT", "Constant", "A constant depth offset along the light ray (Scherzer §4.2)"),
               ("SLOPE", "Slope", "An offset proportional to the receiver's depth slope (Scherzer §4.2)"),
               ("CONSTANT_SLOPE", "Constant + Slope", "Both offsets (Scherzer §4.2)"),
               ("RECEIVER_PLANE", "Receiver Plane", "Each PCF tap is compared with the receiver's own plane there, "
                                                    "less the constant: no acne on any plane, no shadow moved"),
               ("NORMAL_OFFSET", "Normal Offset", "Look the point up moved along its normal, less the constant")))
    constant_bias: FloatProperty(name="Constant Bias", default=ShadowSettings().constant_bias, min=0.0, soft_max=4.0,
                                 description="Depth offset along the light ray, in texels of the receiver (the world "
                                             "width of the map texel at that point)")
    slope_bias: FloatProperty(name="Slope Bias", default=ShadowSettings().slope_bias, min=0.0, soft_max=10.0,
                              description="Multiples of the receiver's depth change over the PCF reach")
    normal_offset: FloatProperty(name="Normal Offset", default=ShadowSettings().normal_offset, min=0.0, soft_max=4.0,
                                 description="How far the point is moved along its normal, in texels of the receiver")
    back_faces: BoolProperty(name="Back Faces", default=False,
                             description="Render back faces into the map (Scherzer §4.2)")
    pcf_kernel: IntProperty(name="PCF k", default=ShadowSettings().pcf_kernel, min=1, max=5,
                            description="k × k percentage-closer filtering: odd k weighs k × k texels alike, "
                                        "even k filters bilinearly (smooth as the point moves)")
    revectorize: BoolProperty(name="Revectorize Edges", default=ShadowSettings().revectorize,
                              description="With PCF 2: put straight shadow edges on the line through the ends of the "
                                          "texel staircase's runs, not on the stairs (silhouette revectorization)")
    mdsm_depths: IntProperty(name="MDSM Depths", default=1, min=1, max=4,
                             description="n of the n-shadow map (Pagot et al. §4.2); 1 = an ordinary map")
    mdsm_selection: EnumProperty(
        name="MDSM Selection", default="MINMAX",
        items=(("MINMAX", "Min/Max", "Keep the min and max of the neighbourhood (Pagot et al. §4.3)"),
               ("SORT", "Sort", "Keep the n sorted depths of the neighbourhood (Pagot et al. §4.3)")))
    mdsm_neighbourhood: IntProperty(name="MDSM Neighbourhood", default=3, min=1, max=7,
                                    description="q of the q × q neighbourhood the depths are selected from")
    eye_blur: FloatProperty(name="Eye Blur", default=0.0, min=0.0, soft_max=8.0, subtype="PIXEL",
                            # no hard max: Blender would clamp a typed 100 silently; shadow_settings refuses it by name
                            description=f"Depth-dependent eye-space blur radius in pixels, 0 = off, at most "
                                        f"{MAX_EYE_BLUR:g} (Scherzer §4.3)")

    # Overlays and live updates
    show_body: BoolProperty(name=OVERLAYS[0][1], description=OVERLAYS[0][2], default=False)
    show_frusta: BoolProperty(name=OVERLAYS[1][1], description=OVERLAYS[1][2], default=False)
    show_warp: BoolProperty(name=OVERLAYS[2][1], description=OVERLAYS[2][2], default=False)
    show_texels: BoolProperty(name=OVERLAYS[3][1], description=OVERLAYS[3][2], default=False)
    show_footprint: BoolProperty(name=OVERLAYS[4][1], description=OVERLAYS[4][2], default=False)
    show_map: BoolProperty(name=OVERLAYS[5][1], description=OVERLAYS[5][2], default=False)
    show_shadowed: BoolProperty(name=OVERLAYS[6][1], description=OVERLAYS[6][2], default=False)
    live_update: BoolProperty(
        name="Live Update", default=True,
        description="Recompute when the camera, the light or objects change (only what changed)")
    body_alpha: FloatProperty(name="Body Opacity", default=0.15, min=0.0, max=1.0, subtype="FACTOR")
    map_pip_size: IntProperty(name="Map Size on Screen", default=256, min=64, max=1024, subtype="PIXEL",
                              description="Side of the picture-in-picture shadow map")

    def check_numbers(self, names: tuple, panel: str) -> None:
        """WarpError naming the first of the float settings ``names`` (shown in the Lixel panel's ``panel``) that is
        NaN: Blender's min and max let a NaN set from Python through, and the core and the shaders compared it as
        nothing (a NaN Constant Bias rendered no shadows, a NaN Normal Offset a black image, a NaN Max Frustum Angle
        cube faces for every point light), without a word."""
        for name in names:
            if math.isnan(getattr(self, name)):
                raise WarpError(f"Scene '{self.id_data.name}' has a {self.bl_rna.properties[name].name} of NaN (set "
                                f"from a script?): give it a number (Lixel panel > {panel} > "
                                f"{self.bl_rna.properties[name].name}), or Reset Settings")

    def warp_options(self) -> WarpOptions:
        """The WarpOptions these settings describe (raises WarpError with a clear message)."""
        self.check_numbers(("plane_budget", "cascade_lambda", "cascade_blend", "max_frustum_angle"), "Method")
        w, h = (int(v) for v in self.shadow_map_size)
        if not (MIN_MAP_SIZE <= w <= MAX_MAP_SIZE and MIN_MAP_SIZE <= h <= MAX_MAP_SIZE):
            raise WarpError(f"Scene '{self.id_data.name}' has a shadow map size of {w}x{h}, out of range: use "
                            f"{MIN_MAP_SIZE}..{MAX_MAP_SIZE} texels per side (Lixel panel > Method > Map Size)")
        planes = self.planes_of_interest()
        vis = None
        if self.use_visible_depth_range:
            near, far = (float(v) for v in self.visible_depth_range)
            if not 0 <= near < far:
                scene = self.id_data
                raise WarpError(f"Scene '{scene.name}' has a Visible Range from {length_text(near, scene)} to "
                                f"{length_text(far, scene)}: its far end must lie beyond its near end "
                                f"(Lixel panel > Method > Visible Range)")
            vis = (near, far)
        if self.use_lambda and not self.lam > 0 and self.method in LAMBDA_METHODS + CASCADE_METHODS:  # (GMNPR splits)
            raise WarpError(f"Scene '{self.id_data.name}' forces λ = {self.lam:g}: a forced λ must be positive; "
                            f"raise it or turn Override λ off (Lixel panel > Method, with GMNPR or GLPR)")
        return WarpOptions(
            shadow_map_size=(w, h), focus=self.focus, lambda_guard=self.lambda_guard,
            texel_snapping=self.texel_snapping, delta_z=self.delta_z,
            visible_depth_range=vis, middle_vector=self.middle_vector, linear_z=self.linear_z,
            lam=float(self.lam) if self.use_lambda else None, max_frustum_angle=float(self.max_frustum_angle),
            planes=planes, plane_budget=float(self.plane_budget), plane_twist=self.plane_twist,
            **{name: getattr(self, name) for name in CASCADE_SETTINGS})

    def planes_of_interest(self) -> tuple:
        """((point, normal[, extent]), ...) of the planes of interest; WarpError naming a bad one."""
        planes = tuple((tuple(p.point), tuple(p.normal)) + ((p.extent_corners(),) if p.corners else ())
                       for p in self.planes)
        for i, (p, (point, normal, *extent)) in enumerate(zip(self.planes, planes)):
            corners = tuple(v for corner in p.extent_corners() for v in corner)
            if not all(math.isfinite(v) for v in point + normal + corners) or not any(normal):
                raise WarpError(f"Plane of interest '{p.label(i)}' of scene '{self.id_data.name}' has a "
                                f"non-finite point or a zero normal: remove it or take it again from the selection "
                                f"(Lixel panel > Method > Planes of Interest)")
        return planes

    def shadow_settings(self) -> ShadowSettings:
        """The ShadowSettings these settings describe (an Eye Blur beyond MAX_EYE_BLUR refused by name, not clamped)."""
        self.check_numbers(("constant_bias", "slope_bias", "normal_offset"), "Shadows")
        if not 0 <= self.eye_blur <= MAX_EYE_BLUR:
            raise WarpError(f"Scene '{self.id_data.name}' has an Eye Blur of {self.eye_blur:g} px, beyond the "
                            f"{MAX_EYE_BLUR:g} px Lixel blurs (each pixel reads (2r + 1)² others): lower it (Lixel "
                            f"panel > Shadows > Eye Blur)")
        return ShadowSettings(
            bias_mode=self.bias_mode, constant_bias=float(self.constant_bias), slope_bias=float(self.slope_bias),
            normal_offset=float(self.normal_offset),
            back_faces=self.back_faces, pcf_kernel=int(self.pcf_kernel), revectorize=self.revectorize,
            mdsm_depths=int(self.mdsm_depths),
            mdsm_selection=self.mdsm_selection, mdsm_neighbourhood=int(self.mdsm_neighbourhood),
            eye_blur=float(self.eye_blur))

    def to_settings(self) -> LixelSettings:
        """The plain ``LixelSettings`` the render engine, scripts and overlays use.
        A scene never set up (``initialised`` False) renders with the add-on
        preferences' defaults, read here and written nowhere: opening a file
        leaves its scenes as they were saved."""
        if not self.initialised:
            prefs = preference_settings()
            if prefs is not None:
                return replace(prefs, warp=replace(prefs.warp, planes=self.planes_of_interest()))
        return LixelSettings(method=self.method, warp=self.warp_options(), shadow=self.shadow_settings())

    def from_settings(self, settings: LixelSettings, planes: bool = True) -> None:
        """Write plain settings into these properties (preferences, scripts); the
        scene counts as set up from then on. ``planes=False`` keeps the planes of
        interest as they are."""
        self.initialised = True  # first: the writes below must not apply the preferences again (_touched)
        if settings.method in available_methods():
            self.method = settings.method
        wo, sh = settings.warp, settings.shadow
        self.shadow_map_size = wo.shadow_map_size
        self.focus = wo.focus
        self.lambda_guard = wo.lambda_guard
        self.texel_snapping = wo.texel_snapping
        self.delta_z = wo.delta_z
        self.use_visible_depth_range = wo.visible_depth_range is not None
        if wo.visible_depth_range is not None:
            self.visible_depth_range = wo.visible_depth_range
        self.middle_vector = wo.middle_vector
        self.linear_z = wo.linear_z
        self.use_lambda = wo.lam is not None
        if wo.lam is not None:
            self.lam = wo.lam
        self.max_frustum_angle = wo.max_frustum_angle
        self.plane_budget = wo.plane_budget
        self.plane_twist = wo.plane_twist
        for name in CASCADE_SETTINGS:
            setattr(self, name, getattr(wo, name))
        if planes:
            self.planes.clear()
            for point, normal, *extent in wo.planes:
                p = self.planes.add()
                p.point, p.normal = point, normal
                p.set_extent(extent[0] if extent and extent[0] is not None else ())
        for name in ("bias_mode", "constant_bias", "slope_bias", "normal_offset", "back_faces", "pcf_kernel",
                     "revectorize", "mdsm_depths", "mdsm_selection", "mdsm_neighbourhood", "eye_blur"):
            setattr(self, name, getattr(sh, name))

    def any_overlay(self) -> bool:
        return any(getattr(self, name) for name, _, _ in OVERLAYS)


CASCADE_SETTINGS = ("cascade_splits", "cascade_warp", "cascade_lambda", "cascade_adaptive", "cascade_stable",
                    "cascade_budget", "cascade_blend")
"""The cascade's WarpOptions fields, stored under the same names."""


def preference_settings():
    """``LixelSettings`` from the add-on preferences, or None when they are not
    available (not registered) or not valid."""
    prefs = addon_preferences()
    if prefs is None:
        return None
    try:
        return prefs.to_settings()
    except WarpError:
        return None


VIEW_PREFERENCES = ("live_update", "body_alpha")
"""The preferences' New Scenes defaults that are no render setting (not in ``LixelSettings``): a new scene takes
them with the rest. (They were shown in the preferences and never applied: Live Update off there left every new
scene updating live.)"""


def take_preferences(props) -> None:
    """Write the add-on preferences' defaults into ``props`` (the planes of interest kept); none where they are not
    available."""
    prefs = preference_settings()
    if prefs is not None:
        props.from_settings(prefs, planes=False)
        for name in VIEW_PREFERENCES:
            setattr(props, name, getattr(addon_preferences(), name))


def ensure_defaults(scene) -> bool:
    """Apply the add-on preferences' defaults to a scene never set up before.
    Returns True if it did. (Not callable from draw code: it writes.)"""
    props = getattr(scene, "lixel", None)
    if props is None or props.initialised:
        return False
    props.initialised = True  # first: the writes must not apply the preferences again (_touched)
    take_preferences(props)
    return True


def _touched(name: str):
    """The update callback of setting ``name``: the user's first edit in a scene
    never set up writes the preference defaults the scene was rendering with,
    then keeps the edited value; from then on the scene is set up and the
    preferences never overwrite it."""
    def update(self, _context):
        if self.initialised:
            return
        value = getattr(self, name)
        value = tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
        self.initialised = True
        take_preferences(self)
        setattr(self, name, value)
    return update


SETTING_NAMES = ("light", "method", "shadow_map_size", "focus", "lambda_guard", "texel_snapping", "delta_z", "use_visible_depth_range",
                 "visible_depth_range", "middle_vector", "linear_z", "use_lambda", "lam", "max_frustum_angle",
                 "plane_budget", "plane_twist", "bias_mode", "constant_bias", "slope_bias", "normal_offset",
                 "back_faces", "pcf_kernel", "revectorize", "mdsm_depths", "mdsm_selection", "mdsm_neighbourhood",
                 "eye_blur") + CASCADE_SETTINGS
for _name in SETTING_NAMES + VIEW_PREFERENCES:  # one update callback for every setting (before registration)
    LixelSceneSettings.__annotations__[_name].keywords["update"] = _touched(_name)

classes = (LixelPlane, LixelSceneSettings)

assert set(BIAS_MODES) == {i[0] for i in LixelSceneSettings.__annotations__["bias_mode"].keywords["items"]}
assert set(MDSM_SELECTIONS) == {i[0] for i in LixelSceneSettings.__annotations__["mdsm_selection"].keywords["items"]}


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.lixel = PointerProperty(type=LixelSceneSettings, name="Lixel")


def unregister():
    del bpy.types.Scene.lixel
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
