/* Depth pass fragment stage for linear z (Scherzer §4.2): the stored depth is
 * z_ndc = depth_row . [world, 1], evaluated per fragment from the
 * perspective-correctly interpolated world position (a per-vertex value would
 * be interpolated linearly in screen space, which is wrong under a
 * perspective light matrix). The matrix's own z / w still clips. */
void main()
{
  float z = dot(u_depth_row, vec4(v_world, 1.0));
  gl_FragDepth = clamp(z * 0.5 + 0.5, 0.0, 1.0);
}
