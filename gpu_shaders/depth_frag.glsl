/* Depth pass fragment stage, compiled only when it has work to do
 * (LIXEL_WRITE_DEPTH): slope-scale bias and/or linear z (Scherzer §4.2).
 *
 * The gpu module has no polygon offset, so the offset of glPolygonOffset is
 * computed here: z_ndc += sign * (c + s * r * (|dz/dx| + |dz/dy|)) with the
 * slope taken per map texel (screen derivatives of the depth pass are per
 * texel). r = max(1, k / 2) is the reach of the k x k PCF kernel: its farthest
 * tap centre lies k/2 texels from the fragment along each axis, where the
 * surface's own depth differs by up to r * (|dz/dx| + |dz/dy|); without it
 * PCF wider than 2x2 shows acne on sloped receivers.
 * sign = +1 for LESS maps (push away from the light), -1 for GREATER.
 * u_bias = (sign, constant c, slope factor s, reach r).
 *
 * Linear z: z_ndc = depth_row . [world, 1], interpolated perspective-correctly
 * through the world position instead of the hyperbolic z / w. */
void main()
{
#ifdef LIXEL_LINEAR_Z
  float z = dot(u_depth_row, vec4(v_world, 1.0));
#else
  float z = gl_FragCoord.z * 2.0 - 1.0;
#endif
  float slope = u_bias.w * (abs(dFdx(z)) + abs(dFdy(z)));
  z += u_bias.x * (u_bias.y + u_bias.z * slope);
  gl_FragDepth = clamp(z * 0.5 + 0.5, 0.0, 1.0);
}
