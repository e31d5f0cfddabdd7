/* Multiple-depth shadow map build (Pagot et al. §4.2-4.3).
 *
 * Each output texel holds n "keys" (depths where smaller = nearer the light;
 * key = depth for LESS maps, 1 - depth for GREATER maps): key 0 is the
 * standard shadow map's own value (§4.3: it "must always" be kept), the others
 * are chosen over the q x q neighbourhood of the standard map:
 *   MINMAX (§4.3 "maximum or minimum"): n=2 -> max; n=3 -> max, min;
 *     n=4 -> max, min and the neighbourhood mean (higher orders are left open
 *     by the paper; the mean is Lixel's choice).
 *   SORT (§4.3 "sorting"): the q*q values are sorted and split into n equal
 *     groups; each group's median represents it, except that the group holding
 *     the standard value is represented by the standard value itself.
 * Unused channels repeat key 0, so they never change a test's outcome.
 * u_params = (n, q, sort (0/1), greater (0/1)). */
float lixel_key(float depth)
{
  return u_params.w > 0.5 ? 1.0 - depth : depth;
}

void main()
{
  ivec2 size = textureSize(u_depth, 0);
  ivec2 t = ivec2(gl_FragCoord.xy);
  int n = int(u_params.x);
  int q = int(u_params.y);
  int r = q / 2;
  float k0 = lixel_key(texelFetch(u_depth, t, 0).r);
  float vals[25];
  int count = 0;
  float lo = k0, hi = k0, sum = 0.0;
  for (int dy = -r; dy <= r; dy++) {
    for (int dx = -r; dx <= r; dx++) {
      ivec2 s = clamp(t + ivec2(dx, dy), ivec2(0), size - 1);
      float k = lixel_key(texelFetch(u_depth, s, 0).r);
      lo = min(lo, k);
      hi = max(hi, k);
      sum += k;
      vals[count++] = k;
    }
  }
  vec4 keys = vec4(k0);
  if (u_params.z < 0.5) {
    if (n >= 2) keys.y = hi;
    if (n >= 3) keys.z = lo;
    if (n >= 4) keys.w = sum / float(count);
  }
  else {
    for (int i = 1; i < count; i++) { /* insertion sort, count <= 25 */
      float v = vals[i];
      int j = i - 1;
      while (j >= 0 && vals[j] > v) {
        vals[j + 1] = vals[j];
        j--;
      }
      vals[j + 1] = v;
    }
    float rep[4];
    int own = 0;
    for (int g = 0; g < 4; g++) {
      int a = (g * count) / n;
      int b = ((g + 1) * count) / n;
      rep[g] = (g < n) ? vals[(a + max(b - 1, a)) / 2] : k0;
      if (g < n && k0 >= vals[a] && k0 <= vals[max(b - 1, a)]) own = g;
    }
    rep[own] = k0;
    /* key 0 stays the standard value; the other groups fill y, z, w in order */
    int c = 1;
    for (int g = 0; g < n; g++) {
      if (g == own) continue;
      if (c == 1) keys.y = rep[g];
      else if (c == 2) keys.z = rep[g];
      else keys.w = rep[g];
      c++;
    }
  }
  out_keys = keys;
}
