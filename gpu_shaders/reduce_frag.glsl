/* One step of a min/max reduction: this texel's block of
 * u_reduce.w x u_reduce.w source texels gives (least, greatest, count) of the
 * values strictly between u_reduce.y and u_reduce.z, or (+big, -big, 0) when
 * none is. The value is the source's channel u_reduce.x (0..3; the first step)
 * or, for later steps (u_reduce.x = -1), the (least, greatest, count) of the
 * step before. */
void main()
{
  ivec2 size = textureSize(u_source, 0);
  int channel = int(u_reduce.x);
  float above = u_reduce.y, below = u_reduce.z;
  int block = int(u_reduce.w);
  ivec2 base = ivec2(gl_FragCoord.xy) * block;
  float lo = 3.0e38, hi = -3.0e38, count = 0.0;
  for (int y = 0; y < block; y++) {
    for (int x = 0; x < block; x++) {
      ivec2 q = base + ivec2(x, y);
      if (q.x >= size.x || q.y >= size.y) continue;
      vec4 v = texelFetch(u_source, q, 0);
      if (channel < 0) {
        lo = min(lo, v.r);
        hi = max(hi, v.g);
        count += v.b;
      }
      else {
        float s = v[channel];
        if (s > above && s < below) {
          lo = min(lo, s);
          hi = max(hi, s);
          count += 1.0;
        }
      }
    }
  }
  out_range = vec4(lo, hi, count, 1.0);
}
