/* A shadow map resampled to the target's size u_range.zw (nearest texel at
 * each pixel centre; or, u_step > 0, every u_step-th texel from texel 0): its
 * window depth in r; or, with LIXEL_STRETCH, a grey picture stretched over the
 * written depths u_range.xy (near the light bright, cleared texels (depth 1)
 * dark blue; addon/ui/renders.py depth_to_rgba is the same picture in numpy). */
void main()
{
  ivec2 size = textureSize(u_map, 0);
  ivec2 t = u_step > 0.0 ? ivec2(gl_FragCoord.xy) * int(u_step)
                         : ivec2(gl_FragCoord.xy * vec2(size) / u_range.zw);
  t = min(t, size - 1);
  float d = texelFetch(u_map, t, 0).r;
#ifdef LIXEL_STRETCH
  if (d >= 1.0) {
    out_preview = vec4(0.05, 0.05, 0.15, 1.0);
  }
  else {
    float lo = u_range.x, hi = u_range.y;
    float g = hi > lo ? (d - lo) / (hi - lo) : 0.5;
    out_preview = vec4(vec3(1.0 - 0.85 * clamp(g, 0.0, 1.0)), 1.0);
  }
#else
  out_preview = vec4(d, 0.0, 0.0, 1.0);
#endif
}
