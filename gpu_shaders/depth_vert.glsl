/* Depth pass (Scherzer §4.2): world -> light clip with u_light. Biasing is
 * applied where the depths are compared (shade_frag.glsl), so this pass is a
 * bare draw: with hyperbolic z the fragment stage is empty and early depth
 * testing stays on. */
invariant gl_Position;

void main()
{
  vec4 world = lixel_instance_matrix() * vec4(pos, 1.0);
#ifdef LIXEL_LINEAR_Z
  v_world = world.xyz;
#endif
  gl_Position = u_light * world;
}
