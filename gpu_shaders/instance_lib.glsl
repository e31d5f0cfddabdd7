/* The instance a vertex belongs to (no per-instance vertex buffers in
 * Blender's gpu module, shared notes §3; addon/gpu/batches.py):
 * u_ids holds the ids (floats, exact below 2^24) of the instances this pass draws, from
 * u_instance_offset on for this draw (gl_InstanceID restarts at 0 for every
 * draw); u_instances holds every instance's object -> world matrix, instance
 * i's columns at texels (4*(i % LIXEL_INSTANCES_PER_ROW) + c,
 * i / LIXEL_INSTANCES_PER_ROW), c = 0..3. Both have LIXEL_INSTANCES_PER_ROW
 * instances per row. */
mat4 lixel_instance_matrix()
{
  int slot = gl_InstanceID + u_instance_offset;
  int i = int(texelFetch(u_ids, ivec2(slot % LIXEL_INSTANCES_PER_ROW, slot / LIXEL_INSTANCES_PER_ROW), 0).r);
  int x = (i % LIXEL_INSTANCES_PER_ROW) * 4;
  int y = i / LIXEL_INSTANCES_PER_ROW;
  return mat4(texelFetch(u_instances, ivec2(x, y), 0),
              texelFetch(u_instances, ivec2(x + 1, y), 0),
              texelFetch(u_instances, ivec2(x + 2, y), 0),
              texelFetch(u_instances, ivec2(x + 3, y), 0));
}
