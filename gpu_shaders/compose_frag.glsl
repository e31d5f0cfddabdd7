/* Compose after the eye-space blur (full screen, one fragment per pixel):
 * out_combined = ambient * albedo + direct * (1 - shadow) where a surface is
 * seen, u_background behind (the world colour, alpha 1; or 0 with Film >
 * Transparent). u_direct = the shading pass's out_color under LIXEL_BLURRED
 * (direct light, alpha = coverage); u_mask = the blurred shadow
 * (eye_blur_frag.glsl); u_ambient = (world colour, albedo). A held-out
 * surface (direct alpha -1, shade_frag.glsl) is (0, 0, 0, 0) with Film
 * Transparent on or off.
 * Without the blur the shading pass writes the combined image itself. */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 direct = texelFetch(u_direct, p, 0);
  float shadow = texelFetch(u_mask, p, 0).r;
  vec3 ambient = u_ambient.rgb;
  out_combined = direct.a > 0.5 ? vec4(direct.rgb * (1.0 - shadow) + u_ambient.a * ambient, 1.0) :
                 direct.a < -0.5 ? vec4(0.0) : u_background;
}
