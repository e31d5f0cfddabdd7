/* The camera draw's position varying (shade_vert.glsl, prepass_frag.glsl).
 * The rasterizer interpolates each varying on its own, in float32. World
 * positions interpolated so erred off a face seen edge-on by 0.06-0.18 mm
 * 25 m away (gen64_04_point_behind_camera; p99 0.015 mm over the view): each
 * coordinate's P / w carries the camera's offset from the origin times 1 / w,
 * whose screen gradient is steep there, and rounds on its own. Three of the
 * camera's clip coordinates instead (x, y and w under a perspective camera,
 * x, y and z under an orthographic one, whose w is 1) have no such term: x / w
 * and y / w are the pixel's, and only the depth along the view is steep, so
 * the rounding moves the point along its eye ray, nearly within the face
 * (there now within 0.004 mm). Each is divided by its row's length: the
 * rows are then unit vectors, nearly orthogonal, and solving them back for P
 * (a 3 x 3 inverse in float32) adds only a few float32 steps of P's size.
 * lixel_camera_rows: those rows' directions as columns, their constant terms
 * and 1 / their lengths. */
/* The clip row that gives the depth along the view: w (3), or z (2) where w
 * is constant (an orthographic camera). */
int lixel_depth_row()
{
  mat4 m = u_view_proj;
  return abs(m[0][3]) + abs(m[1][3]) + abs(m[2][3]) > 0.0 ? 3 : 2;
}

void lixel_camera_rows(out mat3 rows, out vec3 offsets, out vec3 scale)
{
  mat4 m = u_view_proj;
  for (int c = 0; c < 3; c++) {
    int r = c < 2 ? c : lixel_depth_row();
    vec3 row = vec3(m[0][r], m[1][r], m[2][r]);
    scale[c] = inversesqrt(dot(row, row));
    rows[c] = row * scale[c];
    offsets[c] = m[3][r] * scale[c];
  }
}

/* The varying of clip position h. */
vec3 lixel_camera_varying(vec4 h)
{
  mat3 rows;
  vec3 offsets, scale;
  lixel_camera_rows(rows, offsets, scale);
  return vec3(h.x, h.y, h[lixel_depth_row()]) * scale;
}

/* The world position (relative to the frame's origin) of the varying v. */
vec3 lixel_camera_position(vec3 v)
{
  mat3 rows;
  vec3 offsets, scale;
  lixel_camera_rows(rows, offsets, scale);
  return inverse(transpose(rows)) * (v - offsets);
}
