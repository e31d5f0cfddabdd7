/* Depth-dependent eye-space blur of the shadow (Scherzer §4.3): a box blur
 * whose radius is u_blur.x pixels at the nearest visible surface (eye depth
 * u_blur.y) and falls as 1 / eye depth, so near shadows (where projection
 * aliasing is large on screen) are blurred most and distant detail is kept.
 * Only seen pixels contribute (u_data = the shading pass's out_data: shadow
 * in r, eye depth in a: positive where a surface is seen, 0 where nothing is).
 * A surface the light does not light (Light Linking: shadow -1,
 * shade_frag.glsl) has no shadow and lends none to its neighbours.
 * The radius is rounded half to even, like numpy's rint. */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 size = textureSize(u_data, 0);
  vec4 here = texelFetch(u_data, p, 0);
  float radius = u_blur.x, d_near = u_blur.y;
  bool covered = here.a > 0.0 && here.r >= 0.0;
  int r = covered ? int(roundEven(radius * d_near / max(here.a, d_near))) : 0;
  float shadow = covered ? here.r : 0.0;
  if (r > 0) {
    float num = 0.0, den = 0.0;
    for (int dy = -r; dy <= r; dy++) {
      for (int dx = -r; dx <= r; dx++) {
        ivec2 q = p + ivec2(dx, dy);
        if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
        vec4 v = texelFetch(u_data, q, 0);
        if (v.a > 0.0 && v.r >= 0.0) {
          num += v.r;
          den += 1.0;
        }
      }
    }
    shadow = num / max(den, 1e-12);
  }
  out_mask = vec4(shadow, 0.0, 0.0, 1.0);
}
