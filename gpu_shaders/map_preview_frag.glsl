/* A shadow map resampled to the target's size (nearest texel at each pixel
 * centre): its window depth in r; or, with LIXEL_STRETCH, a grey picture
 * stretched over the written depths u_range.xy (near the light bright,
 * cleared texels (depth 1) dark blue). */
void main()
{
  ivec2 size = textureSize(u_map, 0);
  ivec2 t = min(ivec2(gl_FragCoord.xy * vec2(size) / u_range.zw), size - 1);
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
