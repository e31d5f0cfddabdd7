/* The shading pass's background: every target of the shading pass where no
 * receiver is seen (drawn on the far plane over the pre-pass depth, so it
 * reaches exactly the pixels the receivers leave; no target needs a clear).
 * u_background = the world colour with alpha 1 (the combined image; all 0
 * with Film > Transparent), with alpha - 1 where the alpha holds the shadow
 * (LIXEL_SHADOW_ALPHA: none here; finish() reads a negative alpha back as the
 * combined image's alpha - 1), or 0 when the eye-space blur follows (the
 * colour target then holds the light). */
void main()
{
  out_color = u_background;
#ifdef LIXEL_FOOTPRINT
  out_footprint = vec4(0.0, 0.0, 0.0, 1.0);
#endif
#ifdef LIXEL_DATA
  out_data = vec4(0.0);
#endif
#ifdef LIXEL_WORLD
  out_world = vec4(0.0);
#endif
}
