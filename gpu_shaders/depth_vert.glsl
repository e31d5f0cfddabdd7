/* Depth pass (Scherzer §4.2): world -> light clip with u_light.
 * Without LIXEL_WRITE_DEPTH the constant bias is applied here, in NDC units
 * (z_ndc += sign * c, i.e. z_clip += sign * c * w), so the fragment stage stays
 * empty and early depth testing stays on. */
invariant gl_Position;

void main()
{
  vec4 world = lixel_instance_matrix() * vec4(pos, 1.0);
#ifdef LIXEL_WRITE_DEPTH
  v_world = world.xyz;
#endif
  gl_Position = u_light * world;
#ifndef LIXEL_WRITE_DEPTH
  gl_Position.z += u_bias.x * u_bias.y * gl_Position.w;
#endif
}
