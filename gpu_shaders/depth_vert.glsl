/* Depth pass: world -> light clip with u_light. Biasing is applied where the
 * depths are compared (shade_frag.glsl), so this pass is a bare draw.
 *
 * Linear z (Scherzer §4.2, LIXEL_LINEAR_Z): the stored depth is the map's
 * depth row, an affine function of the world position that grows along every
 * light ray, mapped to the window ([-1, 1] -> [0, 1] is folded into
 * u_depth_row on the CPU). An affine function of the world position is exact
 * under perspective-correct ("smooth") interpolation, so one varying carries
 * it and the fragment stage only writes it. Maps whose matrix is affine (a
 * sun's unwarped map) do not come here: their z row is replaced by the depth
 * row on the CPU and they are drawn bare (addon.gpu.pipeline.depth_pass). */
invariant gl_Position;

void main()
{
  vec4 world = lixel_instance_matrix() * vec4(pos, 1.0);
#ifdef LIXEL_LINEAR_Z
  v_depth = dot(u_depth_row, world);
#endif
  gl_Position = u_light * world;
}
