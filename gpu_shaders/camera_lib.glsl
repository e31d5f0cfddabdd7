/* The camera draw's position varying (shade_vert.glsl, prepass_frag.glsl).
 * The rasterizer interpolates each varying on its own, in float32. World
 * positions interpolated so erred off a face seen edge-on by 0.06-0.18 mm
 * 25 m away (gen64_04_point_behind_camera; p99 0.015 mm over the view): each
 * coordinate's P / w carries the camera's offset from the origin times 1 / w,
 * whose screen gradient is steep there, and rounds on its own. Under a
 * perspective camera the varying is therefore P in three of its clip
 * coordinates, x, y and w, which have no such term: x / w and y / w are the
 * pixel's, and only 1 / w is steep, so the rounding moves the point along its
 * eye ray, nearly within the face (there now within 0.004 mm). Each is
 * divided by its row's length, so the rows are unit vectors, nearly
 * orthogonal, and solving them back for P (a 3 x 3 inverse in float32) adds
 * only a few float32 steps of P's size. An orthographic camera interpolates
 * without a 1 / w: there the varying stays P (its clip z would add the depth
 * range's offset, losing 2^-24 of the far distance: 3 µm at 0.5 m for a far of
 * 100 m). The pre-pass's normal comes from the derivatives of P itself
 * (v_world) or of P - C, P relative to the camera's centre (v_from_camera),
 * whichever is shorter (prepass_frag.glsl): on a face along an axis one of
 * their coordinates is the same at every vertex, and each rounds by a
 * float32 step of its own length.
 * lixel_camera_rows: whether the camera is a perspective one, and then those
 * rows' directions as columns, their constant terms and 1 / their lengths.
 * The rows are the same for every vertex of a draw, so the vertex stage solves
 * them once and hands the fragments the solution as flat varyings
 * (v_camera_to_world, v_camera_offsets): per fragment only a 3 x 3 product is
 * left (per fragment, the solve made the pre-pass 1.35-1.5x as long). */
bool lixel_camera_rows(out mat3 rows, out vec3 offsets, out vec3 scale)
{
  mat4 m = u_view_proj;
  vec3 x = vec3(m[0][0], m[1][0], m[2][0]), w = vec3(m[0][3], m[1][3], m[2][3]);
  if (dot(w, w) <= 1e-12 * dot(x, x)) {
    return false; /* orthographic: w's row is the float64 rounding of inverting the camera's matrix, ~1e-17 */
  }
  for (int c = 0; c < 3; c++) {
    int r = c < 2 ? c : 3;
    vec3 row = vec3(m[0][r], m[1][r], m[2][r]);
    scale[c] = inversesqrt(dot(row, row));
    rows[c] = row * scale[c];
    offsets[c] = m[3][r] * scale[c];
  }
  return true;
}

#ifdef LIXEL_VERTEX_STAGE
/* Sets the varying of world position P (relative to the frame's origin),
 * whose clip position is h, and the flat solution that undoes it; and P
 * relative to the camera's centre C (v_from_camera), whose derivatives give
 * the pre-pass's normal. */
void lixel_camera_varyings(vec3 P, vec4 h)
{
  mat3 rows;
  vec3 offsets, scale;
  mat3 to_world = mat3(1.0);
  v_world = P;
  v_camera = P;
  v_camera_offsets = vec3(0.0);
  if (lixel_camera_rows(rows, offsets, scale)) {
    v_camera = vec3(h.x, h.y, h.w) * scale;
    v_camera_offsets = offsets;
    to_world = inverse(transpose(rows));
  }
  v_camera_to_world_x = to_world[0];
  v_camera_to_world_y = to_world[1];
  v_camera_to_world_z = to_world[2];
  v_from_camera = P + to_world * offsets; /* P - C: rows . C + offsets = 0 (orthographic: P) */
}
#else
/* The world position (relative to the frame's origin) of the varyings. */
vec3 lixel_camera_position()
{
  mat3 to_world = mat3(v_camera_to_world_x, v_camera_to_world_y, v_camera_to_world_z);
  return to_world * (v_camera - v_camera_offsets);
}
#endif
