/* A full-screen triangle: pos.xy in clip space. */
void main()
{
  gl_Position = vec4(pos.xy, 0.0, 1.0);
}
