/* Compose (full screen, one fragment per pixel): from the shading pass's
 * out_direct = (direct light * albedo / pi, coverage) and
 * out_data = (shadow, map index, texels per pixel, eye depth):
 *   out_combined  = ambient * albedo + direct * (1 - shadow) where a surface
 *                   is seen, the world colour behind (alpha 1);
 *   out_shadow    = (shadow, 0, 0, 1): 0 lit .. 1 fully shadowed;
 *   out_footprint = the footprint heatmap of the texels per pixel t
 *                   (log2 t / 4 clamped to [-1, 1]: red below one texel per
 *                   pixel (undersampled), green at one, blue above; black
 *                   where nothing is seen).
 * The shadow is the eye-space blurred mask (u_mask) when LIXEL_BLURRED.
 * u_ambient = (world colour, albedo). */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 direct = texelFetch(u_direct, p, 0);
  vec4 data = texelFetch(u_data, p, 0);
  bool covered = direct.a > 0.5;
#ifdef LIXEL_BLURRED
  float shadow = texelFetch(u_mask, p, 0).r;
#else
  float shadow = covered ? data.r : 0.0;
#endif
  vec3 ambient = u_ambient.rgb;
  out_combined = vec4(covered ? direct.rgb * (1.0 - shadow) + u_ambient.a * ambient : ambient, 1.0);
  out_shadow = vec4(shadow, 0.0, 0.0, 1.0);
  float t = clamp(log2(max(covered ? data.b : 0.0, 1e-6)) / 4.0, -1.0, 1.0);
  out_footprint = covered ? vec4(clamp(-t, 0.0, 1.0), 1.0 - abs(t), clamp(t, 0.0, 1.0), 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
