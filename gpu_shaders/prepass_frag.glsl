/* The camera's pre-pass: the depth of what is seen and, for the shading pass
 * (one full-screen pass over this surface, not a second draw of the
 * receivers), the surface itself: its position relative to the frame's
 * origin and its geometric normal, exact per triangle from screen
 * derivatives (helper invocations interpolate the same triangle), stored
 * octahedrally (Cigolle et al., JCGT 2014):
 *   out_surface = (position, octahedral x); out_normal = (octahedral y, ...).
 * The colour targets are not cleared: where the depth says nothing was drawn
 * they hold stale values, which no pass reads. */
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
  out_surface = vec4(v_world, o.x);
  out_normal = vec4(o.y, 0.0, 0.0, 1.0);
}
