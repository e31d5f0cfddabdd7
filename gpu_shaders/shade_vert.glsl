/* Shading pass from the camera (and its depth pre-pass: same vertex stage,
 * invariant position so LESS_EQUAL keeps exactly the pre-pass surfaces). */
invariant gl_Position;

void main()
{
  vec4 world = lixel_instance_matrix() * vec4(pos, 1.0);
  gl_Position = u_view_proj * world;
  lixel_camera_varyings(world.xyz, gl_Position); /* camera_lib.glsl */
}
