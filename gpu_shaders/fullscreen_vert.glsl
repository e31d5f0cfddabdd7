/* A full-screen triangle: pos.xy in clip space; on the far plane (window
 * depth 1) with LIXEL_AT_FAR, so a LESS_EQUAL test passes only where nothing
 * nearer was drawn. */
void main()
{
#ifdef LIXEL_AT_FAR
  gl_Position = vec4(pos.xy, 1.0, 1.0);
#else
  gl_Position = vec4(pos.xy, 0.0, 1.0);
#endif
}
