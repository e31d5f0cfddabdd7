/* Shared by the shading pass's stages (typedef source). std140: every member
 * is a vec4 or mat4, so C-side packing is plain float32 arrays.
 *
 * One LixelMap per ShadowMap of the setup, in selection order (addon.warp.types):
 *   matrix     world -> light clip
 *   depth_row  linear z row (Scherzer §4.2), used when info.w = 1
 *   info       (width, height, greater (0/1), linear z (0/1))
 *   range      (min eye depth, max eye depth, has range (0/1), region vertex count)
 *   plane      region plane (normal.xyz, offset)
 *   extra      (region tolerance, 0, 0, 0)
 *   polygon    region polygon vertices (xyz, 1)
 */
struct LixelMap {
  mat4 matrix;
  vec4 depth_row;
  vec4 info;
  vec4 range;
  vec4 plane;
  vec4 extra;
  vec4 polygon[LIXEL_MAX_POLYGON];
};

/* camera:      (position.xyz, orthographic (0/1))
 * view_dir:    (camera forward.xyz, 0)
 * eye_row:     row 2 of world -> camera (eye depth = -dot(eye_row, [P, 1]))
 * light_pos:   (position.xyz, type: 0 sun, 1 point, 2 spot)
 * light_dir:   (travel direction.xyz, cos of the spot's half angle)
 * light_color: (colour * energy, albedo)
 * params:      (PCF kernel k, MDSM depth count n, map count, spot blend 0..1)
 * bias:        (constant c, slope factor s, PCF reach r, largest slope term), NDC depth units */
struct LixelShade {
  vec4 camera;
  vec4 view_dir;
  vec4 eye_row;
  vec4 light_pos;
  vec4 light_dir;
  vec4 light_color;
  vec4 params;
  vec4 bias;
  LixelMap maps[LIXEL_MAX_MAPS];
};
