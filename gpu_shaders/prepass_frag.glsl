/* The camera's pre-pass: the depth of what is seen and, for the shading pass
 * (one full-screen pass over this surface, not a second draw of the
 * receivers), the surface itself: its position relative to the frame's
 * origin and its geometric normal, per triangle from screen derivatives
 * (helper invocations interpolate the same triangle), stored
 * octahedrally (Cigolle et al., JCGT 2014) in one target:
 *   out_surface = (position, the octahedral normal packed in one float).
 * The packing: the octahedral coordinates in [-1, 1] quantised to 14 and 15
 * bits, stored as the bits of one float: bits 0-14 and 15-28, bit 30 set and
 * bit 29 clear, so its exponent is 128..191 (a finite normal float, no bit
 * pattern a GPU could flush or canonicalise); the normal's direction is then
 * within about 1e-4 rad (lixel_unpack_normal in shade_frag.glsl undoes it),
 * and exact on an axis: the codes 0, 8191, 16382 (0, 16383, 32766) are -1, 0
 * and 1, so a floor or a box's face keeps its normal (2^14 - 1 steps put 0
 * between two codes, 6e-5 rad off: a point light 1 mm above a floor meets it
 * at 1e-4 rad).
 * That matters where the light grazes a receiver: the receiver plane built
 * from the normal is extrapolated to the PCF taps, and an error of 5e-4 rad
 * (12-bit coordinates) showed as acne at 4096² with a bilinear kernel. The
 * colour target is not cleared: where the depth says nothing was drawn it
 * holds stale values, which no pass reads. A held-out receiver (LIXEL_HOLDOUT:
 * addon/scene/instances.py holdout_test) also sets bit 31, the sign, which the
 * unpacking ignores: the shading pass reads a negative code as a holdout. A
 * receiver the light does not light (LIXEL_UNLIT: Light Linking,
 * addon/scene/linking.py) sets bit 29 instead of bit 30 (the exponent stays
 * that of a normal finite float, 2^-63..2^0 rather than 2^1..2^64; setting
 * both could make it an infinity or NaN), which the unpacking ignores too. */
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
   * towards the viewer), from the derivatives of P relative to whichever of
   * the drawing origin and the camera's centre is nearer (camera_lib.glsl):
   * an interpolated position rounds by a float32 step of its distance from
   * its reference, and over a pixel's few millimetres that tilts the
   * normal. Relative to the origin alone it tilted a wall 32 m from there and
   * 5 m from the camera by 2-5e-4 rad, more than a point light 1.7 mm in
   * front of it meets it at, so the wall read as facing away
   * (gen106_05_point_low_in_view, docs/papers.md); relative to the camera
   * alone a floor through the origin lost its exact code on 2.5 % of its
   * pixels (one octahedral step). On a face along an axis the coordinate
   * across it is the same at every vertex, so it stays nearly constant.
   * Both are taken and one kept: derivatives need every fragment of the quad
   * to take them, which a branch per fragment would not guarantee. */
  vec3 n_origin = cross(dFdx(v_world), dFdy(v_world));
  vec3 n_camera = cross(dFdx(v_from_camera), dFdy(v_from_camera));
  vec2 o = lixel_octahedral(dot(v_world, v_world) <= dot(v_from_camera, v_from_camera) ? n_origin : n_camera);
  uvec2 q = uvec2(floor((clamp(o, -1.0, 1.0) + 1.0) * vec2(8191.0, 16383.0) + 0.5));
#ifdef LIXEL_UNLIT
  uint marks = 0x20000000u;
#else
  uint marks = 0x40000000u;
#endif
#ifdef LIXEL_HOLDOUT
  marks |= 0x80000000u;
#endif
  out_surface = vec4(lixel_camera_position(), uintBitsToFloat(marks | (q.x << 15) | q.y));
}
