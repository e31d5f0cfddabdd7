/* Shading pass: per fragment, world position -> light clip of the first map
 * that serves it (regions first, fallback last: ShadowSetup.map_index), a
 * PCF k x k shadow test with texelFetch on an n-depth map (Pagot et al. §4.2:
 * the n-shadow test counts the stored keys nearer the light than the fragment,
 * giving n + 1 outcomes per sample and n*k*k + 1 per PCF(k*k, n)), and Lambert
 * lighting in the light's colour.
 *
 * Outputs: out_direct = (unshadowed direct light * albedo / pi, coverage),
 *          out_data   = (shadow 0..1, map index or -1, shadow-map texels per pixel, eye depth),
 *          out_world  = (world position, 1).
 * The combined image (ambient + direct * (1 - shadow)) is composed after the
 * optional eye-space blur of the shadow channel (Scherzer §4.3). */
#define LIXEL_PI 3.14159265358979

/* Only the samplers of maps that exist are reachable (LIXEL_MAP_COUNT is the
 * setup's map count): a software rasterizer runs every branch a SIMD group
 * disagrees on, so an 8-way switch would cost 8 fetches per tap. */
vec4 lixel_fetch(int i, ivec2 t)
{
#if LIXEL_MAP_COUNT > 1
  if (i == 1) return texelFetch(u_map1, t, 0);
#endif
#if LIXEL_MAP_COUNT > 2
  if (i == 2) return texelFetch(u_map2, t, 0);
#endif
#if LIXEL_MAP_COUNT > 3
  if (i == 3) return texelFetch(u_map3, t, 0);
#endif
#if LIXEL_MAP_COUNT > 4
  if (i == 4) return texelFetch(u_map4, t, 0);
#endif
#if LIXEL_MAP_COUNT > 5
  if (i == 5) return texelFetch(u_map5, t, 0);
#endif
#if LIXEL_MAP_COUNT > 6
  if (i == 6) return texelFetch(u_map6, t, 0);
#endif
#if LIXEL_MAP_COUNT > 7
  if (i == 7) return texelFetch(u_map7, t, 0);
#endif
  return texelFetch(u_map0, t, 0);
}

/* Maps are read in place (lixel.maps[i].member): copying a LixelMap (with its
 * polygon) per fragment is slow on software rasterizers. */
bool lixel_region_contains(int i, vec3 p)
{
  int nv = int(lixel.maps[i].range.w);
  if (nv == 0) {
    return true;
  }
  vec3 n = lixel.maps[i].plane.xyz;
  float tol = lixel.maps[i].extra.x;
  float dist = dot(n, p) - lixel.maps[i].plane.w;
  if (abs(dist) > tol) {
    return false;
  }
  vec3 q = p - dist * n;
  for (int j = 0; j < nv; j++) {
    vec3 a = lixel.maps[i].polygon[j].xyz;
    vec3 b = lixel.maps[i].polygon[(j + 1) % nv].xyz;
    if (dot(cross(b - a, q - a), n) < -tol * length(b - a)) {
      return false;
    }
  }
  return true;
}

void main()
{
  vec3 P = v_world;
  float eye_depth = -dot(lixel.eye_row, vec4(P, 1.0));
  int map_count = int(lixel.params.z);

  int index = -1;
  vec3 ndc = vec3(0.0);
  for (int i = 0; i < map_count; i++) {
    vec4 h = lixel.maps[i].matrix * vec4(P, 1.0);
    if (h.w <= 0.0) continue;
    vec3 c = h.xyz / h.w;
    if (any(greaterThan(abs(c), vec3(1.0)))) continue;
    vec4 range = lixel.maps[i].range;
    if (range.z > 0.5 && (eye_depth < range.x || eye_depth > range.y)) continue;
    if (!lixel_region_contains(i, P)) continue;
    index = i;
    ndc = c;
    break;
  }

  float shadow = 0.0;
  float texels_per_pixel = 0.0;
  if (index >= 0) {
    vec4 info = lixel.maps[index].info;
    ivec2 size = ivec2(info.xy);
    bool greater = info.z > 0.5;
    float z = info.w > 0.5 ? dot(lixel.maps[index].depth_row, vec4(P, 1.0)) : ndc.z;
    float d = z * 0.5 + 0.5;
    float ref = greater ? 1.0 - d : d;
    vec2 tc = (ndc.xy * 0.5 + 0.5) * vec2(size);
    texels_per_pixel = sqrt(abs(determinant(mat2(dFdx(tc), dFdy(tc)))));
    int k = int(lixel.params.x);
    int n = int(lixel.params.y);
    ivec2 base = (k % 2 == 1) ? ivec2(floor(tc)) - (k - 1) / 2 : ivec2(floor(tc - 0.5)) - (k / 2 - 1);
    float hits = 0.0;
    for (int dy = 0; dy < k; dy++) {
      for (int dx = 0; dx < k; dx++) {
        ivec2 s = clamp(base + ivec2(dx, dy), ivec2(0), size - 1);
        vec4 t = lixel_fetch(index, s);
#ifdef LIXEL_MDSM
        /* keys: smaller = nearer the light; channels beyond n repeat key 0 */
        float c = 0.0;
        for (int j = 0; j < n; j++) {
          c += t[j] < ref ? 1.0 : 0.0;
        }
        hits += c / float(n);
#else
        float key = greater ? 1.0 - t.r : t.r;
        hits += key < ref ? 1.0 : 0.0;
#endif
      }
    }
    shadow = hits / float(k * k);
  }

  /* Geometric normal from screen derivatives, turned towards the viewer. */
  vec3 N = normalize(cross(dFdx(P), dFdy(P)));
  vec3 V = lixel.camera.w > 0.5 ? -lixel.view_dir.xyz : lixel.camera.xyz - P;
  if (dot(N, V) < 0.0) {
    N = -N;
  }
  int type = int(lixel.light_pos.w);
  vec3 L;
  float irradiance = 1.0;
  if (type == 0) {
    L = -lixel.light_dir.xyz;
  }
  else {
    vec3 to_light = lixel.light_pos.xyz - P;
    float r2 = max(dot(to_light, to_light), 1e-12);
    L = to_light * inversesqrt(r2);
    irradiance = 1.0 / (4.0 * LIXEL_PI * r2);
    if (type == 2 && dot(-L, lixel.light_dir.xyz) < lixel.light_dir.w) {
      irradiance = 0.0; /* outside the spot cone */
    }
  }
  float ndl = max(dot(N, L), 0.0);
  vec3 direct = lixel.light_color.rgb * (irradiance * ndl * lixel.light_color.w / LIXEL_PI);

  out_direct = vec4(direct, 1.0);
  out_data = vec4(shadow, float(index), texels_per_pixel, eye_depth);
  out_world = vec4(P, 1.0);
}
