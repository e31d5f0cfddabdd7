/* Per-instance object -> world matrices, fetched from an RGBA32F texture
 * (no per-instance vertex buffers in Blender's gpu module, shared notes §3).
 * Instance i's matrix columns are texels (4*(i % LIXEL_INSTANCES_PER_ROW) + c,
 * i / LIXEL_INSTANCES_PER_ROW), c = 0..3. u_instance_offset is the first
 * instance of this draw (gl_InstanceID restarts at 0 for every draw). */
mat4 lixel_instance_matrix()
{
  int i = gl_InstanceID + u_instance_offset;
  int x = (i % LIXEL_INSTANCES_PER_ROW) * 4;
  int y = i / LIXEL_INSTANCES_PER_ROW;
  return mat4(texelFetch(u_instances, ivec2(x, y), 0),
              texelFetch(u_instances, ivec2(x + 1, y), 0),
              texelFetch(u_instances, ivec2(x + 2, y), 0),
              texelFetch(u_instances, ivec2(x + 3, y), 0));
}
