/* The camera's pre-pass: the depth of what is seen and, for the shading pass
 * (one full-screen pass over this surface, not a second draw of the
 * receivers), the surface itself: its position relative to the frame's
 * origin and its geometric normal, exact per triangle from screen
 * derivatives (helper invocations interpolate the same triangle), stored
 * octahedrally (Cigolle et al., JCGT 2014) in one target:
 *   out_surface = (position, the octahedral normal packed in one float).
 * The packing: each octahedral coordinate in [-1, 1] quantised to 12 bits,
 * the two read as one integer below 2^24, which a float holds exactly (no bit
 * pattern a GPU could flush or canonicalise); a step of 2/4095, so the
 * normal's direction is within about 5e-4 rad (lixel_unpack_normal in
 * shade_frag.glsl undoes it). The colour target is not cleared: where the
 * depth says nothing was drawn it holds stale values, which no pass reads. */
vec2 lixel_octahedral(vec3 n)
{
  n /= abs(n.x) + abs(n.y) + abs(n.z);
  vec2 p = n.xy;
  if (n.z < 0.0) {
    p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
  }
  return p;
}

void main()
{
  /* The normal's direction (its length and side are the shading pass's: the
   * octahedral map divides by the L1 norm, and the shading turns the normal
   * towards the viewer). */
  vec2 o = lixel_octahedral(cross(dFdx(v_world), dFdy(v_world)));
  vec2 q = floor(clamp(o * 0.5 + 0.5, 0.0, 1.0) * 4095.0 + 0.5);
  out_surface = vec4(v_world, q.x * 4096.0 + q.y);
}
