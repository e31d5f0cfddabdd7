"""Lixel's add-on preferences: the defaults a new scene's ``scene.lixel`` gets.

``bl_idname`` must be the extension's *root* package (``bl_ext.<repo>.lixel``),
not this module's package, or Blender will not find the preferences.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from ..settings import MAX_MAP_SIZE, MIN_MAP_SIZE, LixelSettings, ShadowSettings
from ..warp.types import WarpOptions
from . import ROOT_PACKAGE, addon_preferences
from .properties import LixelSceneSettings, available_methods, method_items


def _scene_prop(name):
    """The same property definition as the Scene settings (one source of truth)."""
    deferred = LixelSceneSettings.__annotations__[name]
    keywords = {k: v for k, v in deferred.keywords.items() if k != "update"}
    return deferred.function(**keywords)


class LIXEL_AP_preferences(bpy.types.AddonPreferences):
    """Default Lixel settings for scenes that have not been set up yet."""

    bl_idname = ROOT_PACKAGE

    method: EnumProperty(name="Default Method", items=method_items(), default="lispsm",
                         description="The method a new scene starts with")
    map_size: IntProperty(name="Default Map Size", default=2048, min=MIN_MAP_SIZE, max=MAX_MAP_SIZE, soft_max=8192,
                          description=f"Square shadow map side for new scenes (at most {MAX_MAP_SIZE})")
    bias_mode: _scene_prop("bias_mode")
    constant_bias: _scene_prop("constant_bias")
    slope_bias: _scene_prop("slope_bias")
    normal_offset: _scene_prop("normal_offset")
    pcf_kernel: _scene_prop("pcf_kernel")
    mdsm_depths: _scene_prop("mdsm_depths")
    middle_vector: _scene_prop("middle_vector")
    linear_z: _scene_prop("linear_z")
    live_update: BoolProperty(name="Live Update", default=True,
                              description="New scenes recompute when the camera, light or objects change")
    body_alpha: FloatProperty(name="Body Opacity", default=0.15, min=0.0, max=1.0, subtype="FACTOR")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(heading="New Scenes")
        for name in ("method", "map_size", "bias_mode", "constant_bias", "slope_bias", "normal_offset", "pcf_kernel",
                     "mdsm_depths", "middle_vector", "linear_z", "live_update", "body_alpha"):
            col.prop(self, name)

    def to_settings(self) -> LixelSettings:
        method = self.method if self.method in available_methods() else LixelSettings().method
        return LixelSettings(
            method=method,
            warp=WarpOptions(shadow_map_size=(self.map_size, self.map_size), middle_vector=self.middle_vector,
                             linear_z=self.linear_z),
            shadow=ShadowSettings(bias_mode=self.bias_mode, constant_bias=self.constant_bias,
                                  slope_bias=self.slope_bias, normal_offset=self.normal_offset,
                                  pcf_kernel=self.pcf_kernel,
                                  mdsm_depths=self.mdsm_depths))


preferences = addon_preferences
"""The registered preferences, or None."""


classes = (LIXEL_AP_preferences,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(classes)
