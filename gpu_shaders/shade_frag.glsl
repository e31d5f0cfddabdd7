/* Shading pass: one full-screen pass over the surface the camera pre-pass saw
 * (prepass_frag.glsl: position and normal per pixel), so each pixel is shaded
 * once whatever the depth complexity, and the receivers are drawn once. Per
 * pixel: the world position -> light clip of the first map that serves it
 * (regions first, fallback last: ShadowSetup.map_index), a PCF k x k shadow
 * test on an n-depth map (Pagot et al. §4.2: the n-shadow test counts the
 * stored keys nearer the light than the fragment, giving n + 1 outcomes per
 * sample and n*k*k + 1 per PCF(k*k, n)), and Lambert lighting in the light's
 * colour.
 *
 * Biasing (Scherzer §4.2) is applied to the fragment's depth before the test,
 * in NDC depth units: z -= c + s * r * (|dz/du| + |dz/dv|) towards the light,
 * with dz/du, dz/dv the depth slope of the fragment's own triangle per map
 * texel (the polygon-offset slope, which the gpu module cannot set on the depth
 * pass). It is computed exactly from the triangle's normal and the map's
 * Jacobian at the fragment (see lixel_depth_slope), so the depth pass stays a
 * bare draw. r = max(1, k / 2) is the PCF reach: the farthest tap centre lies
 * k/2 texels away along each axis, where the surface's own depth differs by up
 * to r * (|dz/du| + |dz/dv|).
 *
 * One variant per configuration (addon/gpu/shaders.py ShadeVariant): a
 * software rasterizer runs every branch that a SIMD group of fragments
 * disagrees on, and every iteration of a loop whose count it cannot see, so
 * what the setup and settings fix is compiled in rather than branched on:
 *   LIXEL_MAP_COUNT  maps (1..8; with one map and neither regions nor depth
 *                    ranges the map is chosen without a loop)
 *   LIXEL_REGIONS / LIXEL_RANGES  some map has a region / a view depth range
 *   LIXEL_LIGHT      0 sun, 1 point, 2 spot
 *   LIXEL_PCF        the PCF kernel k;  LIXEL_MDSM  n > 1 depths per texel
 *   LIXEL_SLOPE_BIAS the slope-scale term is on
 *   LIXEL_BLURRED    the eye-space blur follows: out_color is the unshadowed
 *                    light (compose_frag.glsl shadows it after the blur)
 *   LIXEL_SHADOW_TARGET / LIXEL_FOOTPRINT / LIXEL_DATA / LIXEL_WORLD
 *                    the optional targets (what the frame reads back)
 *
 * Outputs (addon/gpu/pipeline.py ShadowFrame.shade):
 *   out_color     = (ambient * albedo + direct * (1 - shadow), 1), or
 *                   (direct, 1) with LIXEL_BLURRED; direct = light * albedo / pi
 *   out_shadow    = (shadow 0..1, 0, 0, 1), LIXEL_SHADOW_TARGET
 *   out_footprint = the footprint heatmap of the texels per pixel t
 *                   (log2 t / 4 clamped to [-1, 1]: red below one texel per
 *                   pixel (undersampled), green at one, blue above), LIXEL_FOOTPRINT
 *   out_data      = (shadow, map index or -1, texels per pixel, eye depth), LIXEL_DATA
 *   out_world     = (world position, 1), LIXEL_WORLD
 * Pixels no surface covers keep the targets' clear values (the world colour
 * in out_color, zero elsewhere, black in out_footprint).
 * Positions are relative to the frame's origin; the uniform block `lixel` is
 * declared in addon/gpu/layout.py (LIXEL_SHADE). */
#define LIXEL_PI 3.14159265358979

/* Only the samplers of maps that exist are reachable (LIXEL_MAP_COUNT is the
 * setup's map count): an 8-way switch would cost 8 fetches per tap. */
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

vec4 lixel_gather(int i, vec2 uv)
{
#if LIXEL_MAP_COUNT > 1
  if (i == 1) return textureGather(u_map1, uv);
#endif
#if LIXEL_MAP_COUNT > 2
  if (i == 2) return textureGather(u_map2, uv);
#endif
#if LIXEL_MAP_COUNT > 3
  if (i == 3) return textureGather(u_map3, uv);
#endif
#if LIXEL_MAP_COUNT > 4
  if (i == 4) return textureGather(u_map4, uv);
#endif
#if LIXEL_MAP_COUNT > 5
  if (i == 5) return textureGather(u_map5, uv);
#endif
#if LIXEL_MAP_COUNT > 6
  if (i == 6) return textureGather(u_map6, uv);
#endif
#if LIXEL_MAP_COUNT > 7
  if (i == 7) return textureGather(u_map7, uv);
#endif
  return textureGather(u_map0, uv);
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

vec3 lixel_row(mat4 m, int r)
{
  return vec3(m[0][r], m[1][r], m[2][r]);
}

/* |dz/du| + |dz/dv|: how much the stored depth (NDC units, hyperbolic or
 * linear) of the plane through P with normal N changes per map texel, from
 * two tangents of the plane pushed through the map's Jacobian at P. */
float lixel_depth_slope(int i, vec3 P, vec3 N, vec4 h, vec3 ndc, vec2 size)
{
  mat4 M = lixel.maps[i].matrix;
  vec3 w_row = lixel_row(M, 3);
  vec3 gx = (lixel_row(M, 0) - ndc.x * w_row) / h.w;
  vec3 gy = (lixel_row(M, 1) - ndc.y * w_row) / h.w;
  vec3 gz = lixel.maps[i].info.w > 0.5 ? lixel.maps[i].depth_row.xyz : (lixel_row(M, 2) - ndc.z * w_row) / h.w;
  vec3 t1 = normalize(abs(N.x) < 0.9 ? cross(N, vec3(1.0, 0.0, 0.0)) : cross(N, vec3(0.0, 1.0, 0.0)));
  vec3 t2 = cross(N, t1);
  float x1 = dot(gx, t1), y1 = dot(gy, t1), z1 = dot(gz, t1);
  float x2 = dot(gx, t2), y2 = dot(gy, t2), z2 = dot(gz, t2);
  float det = x1 * y2 - x2 * y1;
  float limit = lixel.bias.w;
  if (abs(det) < 1e-30) {
    return limit; /* the plane contains the light ray: unbounded slope */
  }
  float a = (z1 * y2 - z2 * y1) / det; /* dz / dx_ndc */
  float b = (x1 * z2 - x2 * z1) / det; /* dz / dy_ndc */
  return min(abs(a) * 2.0 / size.x + abs(b) * 2.0 / size.y, limit);
}

vec4 lixel_footprint_colour(float texels_per_pixel)
{
  float t = clamp(log2(max(texels_per_pixel, 1e-6)) / 4.0, -1.0, 1.0);
  return vec4(clamp(-t, 0.0, 1.0), 1.0 - abs(t), clamp(t, 0.0, 1.0), 1.0);
}

/* One texel's shadow test against the fragment's reference depth: 0 or 1, or
 * with n depths per texel the n-shadow test's fraction (MDSM §4.2; keys:
 * smaller = nearer the light, channels beyond n repeat key 0). */
float lixel_test(int m, ivec2 s, float ref, bool greater)
{
  vec4 t = lixel_fetch(m, s);
#ifdef LIXEL_MDSM
  float c = 0.0;
  for (int j = 0; j < LIXEL_MDSM; j++) {
    c += t[j] < ref ? 1.0 : 0.0;
  }
  return c / float(LIXEL_MDSM);
#else
  float key = greater ? 1.0 - t.r : t.r;
  return key < ref ? 1.0 : 0.0;
#endif
}

/* Whether map i serves P (clip volume, depth range, region); h = its clip position. */
bool lixel_serves(int i, vec3 P, float eye_depth, out vec4 h)
{
  h = lixel.maps[i].matrix * vec4(P, 1.0);
  if (h.w <= 0.0 || any(greaterThan(abs(h.xyz / h.w), vec3(1.0)))) {
    return false;
  }
#ifdef LIXEL_RANGES
  vec4 range = lixel.maps[i].range;
  if (range.z > 0.5 && (eye_depth < range.x || eye_depth > range.y)) {
    return false;
  }
#endif
#ifdef LIXEL_REGIONS
  if (!lixel_region_contains(i, P)) {
    return false;
  }
#endif
  return true;
}

vec3 lixel_unoctahedral(vec2 p)
{
  vec3 n = vec3(p, 1.0 - abs(p.x) - abs(p.y));
  float t = max(-n.z, 0.0);
  n.xy += vec2(n.x >= 0.0 ? -t : t, n.y >= 0.0 ? -t : t);
  return normalize(n);
}

#if defined(LIXEL_FOOTPRINT) || defined(LIXEL_DATA)
/* The point of the plane through P with normal N that the camera sees at
 * window position w (pixel units): where the camera ray through w crosses the
 * plane. */
vec3 lixel_on_plane(vec2 w, vec3 P, vec3 N)
{
  vec2 ndc = w * lixel.screen.xy - 1.0;
  vec4 a = lixel.inv_view_proj * vec4(ndc, -1.0, 1.0);
  vec4 b = lixel.inv_view_proj * vec4(ndc, 1.0, 1.0);
  vec3 o = a.xyz / a.w;
  vec3 d = b.xyz / b.w - o;
  return o + d * (dot(N, P - o) / dot(N, d));
}

vec2 lixel_texel_of(int m, vec3 P, vec2 size)
{
  vec4 h = lixel.maps[m].matrix * vec4(P, 1.0);
  return (h.xy / h.w * 0.5 + 0.5) * size;
}

/* Shadow-map texels per pixel: sqrt |det| of the texel position's change to
 * the next pixel right and up, on the pixel's own plane (what a geometry
 * pass's screen derivatives give: its helper invocations interpolate the same
 * triangle). */
float lixel_texels_per_pixel(int m, vec3 P, vec3 N, vec2 tc, vec2 size)
{
  vec2 dx = lixel_texel_of(m, lixel_on_plane(gl_FragCoord.xy + vec2(1.0, 0.0), P, N), size) - tc;
  vec2 dy = lixel_texel_of(m, lixel_on_plane(gl_FragCoord.xy + vec2(0.0, 1.0), P, N), size) - tc;
  return sqrt(abs(determinant(mat2(dx, dy))));
}
#endif

void main()
{
  /* The surface the pre-pass saw here (prepass_frag.glsl); this pass runs only
   * where it saw one (a full-screen triangle on the far plane, GREATER). */
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 surface = texelFetch(u_surface, px, 0);
  vec3 P = surface.xyz;
  vec3 N = lixel_unoctahedral(vec2(surface.w, texelFetch(u_normal, px, 0).r));
  float eye_depth = -dot(lixel.eye_row, vec4(P, 1.0));

  /* The first map that serves P. */
  int index = -1;
  vec4 hsel = vec4(0.0, 0.0, 0.0, 1.0);
#if LIXEL_MAP_COUNT == 1
  const int m = 0;
  if (lixel_serves(0, P, eye_depth, hsel)) {
    index = 0;
  }
#else
  for (int i = 0; i < LIXEL_MAP_COUNT; i++) {
    vec4 h;
    if (lixel_serves(i, P, eye_depth, h)) {
      index = i;
      hsel = h;
      break;
    }
  }
  int m = max(index, 0);
#endif
  vec3 ndc = hsel.xyz / hsel.w;
  vec4 info = lixel.maps[m].info;
  ivec2 size = ivec2(info.xy);
  vec2 tc = (ndc.xy * 0.5 + 0.5) * vec2(size);
#if defined(LIXEL_FOOTPRINT) || defined(LIXEL_DATA)
  float texels_per_pixel = index >= 0 ? lixel_texels_per_pixel(m, P, N, tc, vec2(size)) : 0.0;
#else
  float texels_per_pixel = 0.0;
#endif

  float shadow = 0.0;
  if (index >= 0) {
    bool greater = info.z > 0.5;
    float z = info.w > 0.5 ? dot(lixel.maps[m].depth_row, vec4(P, 1.0)) : ndc.z;
    float bias = lixel.bias.x;
#ifdef LIXEL_SLOPE_BIAS
    bias += lixel.bias.y * lixel.bias.z * lixel_depth_slope(m, P, N, hsel, ndc, vec2(size));
#endif
    z += greater ? bias : -bias; /* towards the light */
    float d = z * 0.5 + 0.5;
    float ref = greater ? 1.0 - d : d;
    const int k = LIXEL_PCF;
    ivec2 base = (k % 2 == 1) ? ivec2(floor(tc)) - (k - 1) / 2 : ivec2(floor(tc - 0.5)) - (k / 2 - 1);
    float hits = 0.0;
#if defined(LIXEL_MDSM) || LIXEL_PCF == 1
    for (int dy = 0; dy < k; dy++) {
      for (int dx = 0; dx < k; dx++) {
        hits += lixel_test(m, clamp(base + ivec2(dx, dy), ivec2(0), size - 1), ref, greater);
      }
    }
#else
    /* The k x k taps as 2 x 2 gathers (a gather costs about one texelFetch on
     * a software rasterizer): the gather at the corner between texels c and
     * c + 1 returns (c, c+1) x (c, c+1), clamped to the edge like the taps,
     * as x = (c, c+1), y = (c+1, c+1), z = (c+1, c), w = (c, c). Taps beyond
     * k - 1 are not counted. */
    for (int gy = 0; gy < k; gy += 2) {
      for (int gx = 0; gx < k; gx += 2) {
        vec4 t = lixel_gather(m, (vec2(base + ivec2(gx, gy)) + 1.0) / vec2(size));
        vec4 key = greater ? 1.0 - t : t;
        vec4 counted = vec4(gy + 1 < k ? 1.0 : 0.0, (gx + 1 < k && gy + 1 < k) ? 1.0 : 0.0,
                            gx + 1 < k ? 1.0 : 0.0, 1.0);
        hits += dot(counted, vec4(lessThan(key, vec4(ref))));
      }
    }
#endif
    shadow = hits / float(k * k);
#ifdef LIXEL_REGIONS
    /* A plane map (a map with a region) samples each pixel's own point of its
     * plane (Chong-Gortler §2): the test of that one lixel is the exact shadow
     * there, and the k x k taps would only blur it over k pixels. */
    if (lixel.maps[m].range.w > 0.5) {
      shadow = lixel_test(m, ivec2(floor(tc)), ref, greater);
    }
#endif
  }

  vec3 L;
  float irradiance = 1.0;
#if LIXEL_LIGHT == 0
  L = -lixel.light_dir.xyz;
#else
  vec3 to_light = lixel.light_pos.xyz - P;
  float r2 = max(dot(to_light, to_light), 1e-12);
  L = to_light * inversesqrt(r2);
  irradiance = 1.0 / (4.0 * LIXEL_PI * r2);
#  if LIXEL_LIGHT == 2
  /* Blender's spot mask: smoothstep over the outer blend * (1 - cos half) of the cone. */
  float cos_half = lixel.light_dir.w;
  float x = dot(-L, lixel.light_dir.xyz) - cos_half;
  float blend = lixel.spot.x * (1.0 - cos_half);
  irradiance *= blend > 0.0 ? smoothstep(0.0, 1.0, x / blend) : step(0.0, x);
#  endif
#endif
  float ndl = max(dot(N, L), 0.0);
  vec3 direct = lixel.light_color.rgb * (irradiance * ndl * lixel.light_color.w / LIXEL_PI);

#ifdef LIXEL_BLURRED
  out_color = vec4(direct, 1.0);
#else
  out_color = vec4(direct * (1.0 - shadow) + lixel.ambient.rgb * lixel.light_color.w, 1.0);
#endif
#ifdef LIXEL_SHADOW_TARGET
  out_shadow = vec4(shadow, 0.0, 0.0, 1.0);
#endif
#ifdef LIXEL_FOOTPRINT
  out_footprint = lixel_footprint_colour(texels_per_pixel);
#endif
#ifdef LIXEL_DATA
  out_data = vec4(shadow, float(index), texels_per_pixel, eye_depth);
#endif
#ifdef LIXEL_WORLD
  out_world = vec4(P, 1.0);
#endif
}
