/* Shading pass: one full-screen pass over the surface the camera pre-pass saw
 * (prepass_frag.glsl: position and normal per pixel), so each pixel is shaded
 * once whatever the depth complexity, and the receivers are drawn once. Per
 * pixel: the world position -> light clip of the first map that serves it
 * (regions first, fallback last: ShadowSetup.map_index), a PCF k x k shadow
 * test (lixel_weight: an odd k weighs its k x k nearest texels alike; an even k
 * filters bilinearly, so the shadow moves smoothly with the point: k = 2 is
 * the bilinear PCF of graphics hardware, k = 4 a 3 x 3 box of bilinear taps;
 * k = 2 with its straight edges revectorized on request: lixel_revectorized)
 * on an n-depth map (Pagot et al. §4.2: the n-shadow test counts the
 * stored keys nearer the light than the fragment, giving n + 1 outcomes per
 * sample and n*k*k + 1 per PCF(k*k, n)), and Lambert lighting in the light's
 * colour.
 *
 * Biasing (Scherzer §4.2) happens here, where depths are compared, so the depth
 * pass stays a bare draw. Its unit is the receiver's own texel: w_t, the world
 * width at P of the map texel that holds P, measured across the light ray
 * (from the map's Jacobian at P; the geometric mean of the texel's sides),
 * turned into stored depth along the light ray at P (u = w_t |dz/ds|). One
 * setting then means the same for every method, light type, map size and
 * scene scale. lixel.bias = (c, s, r, mode); the mode is compiled in
 * (LIXEL_BIAS):
 *
 *   RECEIVER_PLANE (the default): each PCF tap is compared with the depth of
 *     the receiver's own plane where the light ray through that tap's texel
 *     centre meets it (exactly, for any projective map and either depth:
 *     lixel_receiver), or with P's own depth where that plane recedes from
 *     the light, less c texels (receiver-plane depth bias, Isidoro, GDC 2006,
 *     made one-sided). A planar receiver then never shadows itself however
 *     steep it is or wide the kernel, a concave crease (a wall's foot) does
 *     not darken the ground beside it through the kernel's far taps, and no
 *     shadow moves: c only absorbs rounding and faceting. The plane's own
 *     error is added: the pre-pass normal's (LIXEL_NORMAL_ERROR) moves the
 *     plane's depth at the PCF reach by r e / (n.l)^2 texels, which passes c
 *     where the light grazes the receiver (n.l < ~0.01). A tap that stored
 *     something past the plane yet nearer the light than P missed the
 *     receiver (a grazed wall is under a texel wide across the light) and is
 *     left out of every filter (lixel_seen, lixel_judge).
 *   NORMAL_OFFSET: the point looked up is P moved s texels along its normal
 *     (towards the light), less c texels.
 *   CONSTANT, SLOPE, CONSTANT_SLOPE: the classic offsets, c texels plus
 *     s times the receiver's depth change over the PCF reach r = max(1, k / 2)
 *     (the polygon-offset slope, exact from the triangle's normal;
 *     lixel_receiver), the slope term clamped at LIXEL_SLOPE_LIMIT texels.
 *   NONE: the raw comparison.
 *
 * One variant per configuration (addon/gpu/shaders.py ShadeVariant): a
 * software rasterizer runs every branch that a SIMD group of fragments
 * disagrees on, and every iteration of a loop whose count it cannot see, so
 * what the setup and settings fix is compiled in rather than branched on:
 *   LIXEL_MAP_COUNT  maps (1..8; with one map and neither regions nor depth
 *                    ranges the map is chosen without a loop)
 *   LIXEL_REGIONS / LIXEL_RANGES  some map has a region / a view depth range
 *   LIXEL_BLENDS     some map has a blend band (a cascade's seams)
 *   LIXEL_LIGHT      0 sun, 1 point, 2 spot
 *   LIXEL_PCF        the PCF kernel k;  LIXEL_MDSM  n > 1 depths per texel
 *   LIXEL_REVECTORIZE  k = 2 puts straight edges on their line (lixel_run)
 *   LIXEL_BIAS       the bias mode (LIXEL_BIAS_*, addon.gpu.shaders.BIAS_CODES)
 *   LIXEL_MAPS_LINEAR / LIXEL_MAPS_GREATER  1 or 0 when every map stores a
 *                    linear depth row / tests GREATER, or not one does
 *                    (undefined where maps differ: read per map)
 *   LIXEL_BLURRED    the eye-space blur follows: out_color is the unshadowed
 *                    light (compose_frag.glsl shadows it after the blur)
 *   LIXEL_SHADOW_ALPHA  the shadow goes into out_color's alpha (the Shadow
 *                    pass; the combined image's alpha, 1, is set on read-back)
 *   LIXEL_FOOTPRINT / LIXEL_DATA / LIXEL_WORLD
 *                    the optional targets (what the frame reads back)
 *
 * Outputs (addon/gpu/pipeline.py ShadowFrame.shade):
 *   out_color     = (ambient * albedo + direct * (1 - shadow), 1), or
 *                   (direct, 1) with LIXEL_BLURRED; direct = light * albedo / pi;
 *                   alpha = the shadow 0..1 with LIXEL_SHADOW_ALPHA
 *   out_footprint = the footprint heatmap of the texels per pixel t
 *                   (log2 t / 4 clamped to [-1, 1]: red below one texel per
 *                   pixel (undersampled), green at one, blue above), LIXEL_FOOTPRINT
 *   out_data      = (shadow, map index or -1, texels per pixel, eye depth), LIXEL_DATA
 *   out_world     = (world position, the pre-pass's packed normal), LIXEL_WORLD
 *                   (which surface the pixel shows: result.unpack_normals)
 * A held-out surface (LIXEL_HOLDOUT: the pre-pass's packed normal negative)
 * is not shaded: out_color = (0, 0, 0, 0), the transparent hole Cycles leaves
 * with Film Transparent on or off, its alpha -1 where the alpha holds the
 * shadow or the light (ShadowFrame.finish and compose_frag.glsl read it as 0,
 * with no shadow), and the other targets as where nothing is seen, but for
 * out_data's eye depth, negated (the eye blur's radius still counts it).
 * A surface the light does not light (LIXEL_UNLIT: Light Linking, bit 30 of
 * the packed normal clear, prepass_frag.glsl) gets the ambient term alone and no shadow (as in Cycles,
 * where such an object gets no direct light from it, so nothing to shadow);
 * out_data's shadow is -1 there, which the eye blur neither blurs nor spreads.
 * Pixels no surface covers get background_frag.glsl's values (the world
 * colour in out_color, with no shadow; zero elsewhere, black in out_footprint).
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

/* Bias modes (the LIXEL_BIAS define), as addon.gpu.shaders.BIAS_CODES. */
#define LIXEL_BIAS_NONE 0
#define LIXEL_BIAS_CONSTANT 1
#define LIXEL_BIAS_SLOPE 2
#define LIXEL_BIAS_CONSTANT_SLOPE 3
#define LIXEL_BIAS_RECEIVER_PLANE 4
#define LIXEL_BIAS_NORMAL_OFFSET 5
/* The slope term's ceiling in texels (a depth-bias clamp: a surface nearly
 * edge-on to the light has an unbounded slope). */
#define LIXEL_SLOPE_LIMIT 16.0
/* The pre-pass normal's direction error in radians (its 14/15-bit packing
 * and the float32 screen derivatives it comes from; prepass_frag.glsl). */
#define LIXEL_NORMAL_ERROR 1e-4
/* The narrowest texel the bias is measured in, a fraction of the distance
 * from the frame's origin (16 float32 steps: lixel_receiver). */
#define LIXEL_FLOAT_WIDTH 1e-6
/* A point within this many lixels of a plane map's lixel centre is that
 * lixel's own point (float32 rounding, 2e-3 measured; one lixel per pixel). */
#define LIXEL_ON_LIXEL 0.0625

/* Whether map i stores its linear depth row, and whether its depth test is
 * GREATER: constants where every map agrees (LIXEL_MAPS_*), so that only one
 * side of each choice below is computed. */
bool lixel_linear(int i)
{
#ifdef LIXEL_MAPS_LINEAR
  return LIXEL_MAPS_LINEAR == 1;
#else
  return lixel.maps[i].info.w > 0.5;
#endif
}

bool lixel_greater(int i)
{
#ifdef LIXEL_MAPS_GREATER
  return LIXEL_MAPS_GREATER == 1;
#else
  return lixel.maps[i].info.z > 0.5;
#endif
}

/* The stored depth (NDC units, linear or hyperbolic) of world point P in map i,
 * whose clip position is h. */
float lixel_stored_depth(int i, vec3 P, vec4 h)
{
  return lixel_linear(i) ? dot(lixel.maps[i].depth_row, vec4(P, 1.0)) : h.z / h.w;
}

/* The receiver's depth at P in map i over its neighbourhood, and the unit of
 * every bias: what lixel_tap_depth needs per tap. */
struct LixelReceiver {
  float z;      /* stored depth of P (NDC units) */
  float width;  /* w_t: a texel's world width at P across the light ray */
  float texel;  /* u: one texel width along the light ray at P, in stored depth units */
  float slope;  /* |dz/du| + |dz/dv|: the plane's depth change per texel (SLOPE modes) */
  vec3 rho;     /* RECEIVER_PLANE: tap depth = dot(rho, p) / dot(sigma, p), p = (x_ndc, y_ndc, 1) */
  vec3 sigma;
  float det;    /* sign of dot(sigma, p) on the receiver's side of its horizon; 0: no plane */
};

/* The receiver plane through P with normal N in map i (clip position h, NDC
 * ndc): how its stored depth varies over the map's image. Parametrise the
 * plane as P + a t1 + b t2; the map sends it to the image by the 3 x 3
 * projective map A = [M t1 | M t2 | M P] (rows x, y, w), and the stored depth
 * is D . (a, b, 1) / W . (a, b, 1) with D, W from the depth row (linear: W =
 * (0, 0, 1)) or the matrix's z and w rows (hyperbolic). For an image point p
 * = (x, y, 1), (a, b, 1) ~ adj(A) p, so the depth where the light ray through
 * p meets the plane is (D adj(A) p) / (W adj(A) p): exact for every
 * projective map (perspective warps, point lights, plane maps), with adj(A)'s
 * rows the cross products of A's columns. Also the slope per texel (first
 * order at P, for the SLOPE modes) and the texel unit u. */
LixelReceiver lixel_receiver(int i, vec3 P, vec3 N, vec3 L, vec4 h, vec2 size, bool plane, bool slope)
{
  LixelReceiver r;
  mat4 M = lixel.maps[i].matrix;
  bool linear = lixel_linear(i);
  vec3 rx = lixel_row(M, 0), ry = lixel_row(M, 1), rz = lixel_row(M, 2), rw = lixel_row(M, 3);
  vec3 ndc = h.xyz / h.w;
  /* The map's Jacobian at P: NDC x, y and stored depth per metre. */
  vec3 gx = (rx - ndc.x * rw) / h.w;
  vec3 gy = (ry - ndc.y * rw) / h.w;
  vec3 gz = linear ? lixel.maps[i].depth_row.xyz : (rz - ndc.z * rw) / h.w;
  /* A texel's world width at P across the light ray (x, y are constant along
   * it, so |gx|, |gy| are the across-ray rates; the geometric mean of its two
   * sides, so a long thin texel of a warped or plane map does not lift the
   * bias to its long side), and that width as stored depth along the ray. */
  r.width = 2.0 * inversesqrt(sqrt(size.x * size.x * dot(gx, gx) * size.y * size.y * dot(gy, gy)));
  /* No narrower than float32 resolves P: P and the maps' depths are
   * interpolated in float32 from vertices relative to the frame's origin,
   * about as far from it as P or the camera, so both err by some 2^-24 of
   * that distance; a texel finer than that (an orthographic view 2e-5 m
   * wide 10 m from the origin) would bias by less than the error: acne. */
  r.width = max(r.width, LIXEL_FLOAT_WIDTH * max(length(P), length(lixel.camera.xyz)));
  r.texel = r.width * abs(dot(gz, L));
  r.z = linear ? dot(lixel.maps[i].depth_row, vec4(P, 1.0)) : ndc.z;
  r.det = 0.0;
  r.slope = 0.0;
  if (!plane && !slope) {
    return r;
  }
  /* Two tangents of the plane (any two independent ones: their scale cancels). */
  vec3 t1 = abs(N.x) < 0.9 ? vec3(0.0, N.z, -N.y) : vec3(-N.z, 0.0, N.x); /* N x e_x, N x e_y */
  vec3 t2 = cross(N, t1);
  vec3 c0 = vec3(dot(rx, t1), dot(ry, t1), dot(rw, t1));
  vec3 c1 = vec3(dot(rx, t2), dot(ry, t2), dot(rw, t2));
  vec3 c2 = h.xyw;
  vec3 a0 = cross(c1, c2), a1 = cross(c2, c0), a2 = cross(c0, c1);  /* rows of adj(A) */
  r.det = dot(c0, a0);
  vec3 D = linear ? vec3(dot(gz, t1), dot(gz, t2), r.z) : vec3(dot(rz, t1), dot(rz, t2), h.z);
  r.rho = D.x * a0 + D.y * a1 + D.z * a2;
  r.sigma = linear ? a2 : c0.z * a0 + c1.z * a1 + h.w * a2;
  if (slope) {
    /* First-order slope at P: dz / dx_ndc, dz / dy_ndc = (rho.xy - z sigma.xy) / sigma(p). */
    float s0 = dot(r.sigma, vec3(ndc.xy, 1.0));
    float limit = LIXEL_SLOPE_LIMIT * r.texel;
    if (abs(s0) > 0.0 && abs(r.det) > 0.0) {
      vec2 g = (r.rho.xy - r.z * r.sigma.xy) / s0;
      r.slope = min(abs(g.x) * 2.0 / size.x + abs(g.y) * 2.0 / size.y, limit);
    }
    else {
      r.slope = limit; /* the plane contains the light ray: unbounded slope */
    }
  }
  return r;
}

/* The reference depths (window units, keys: smaller = nearer the light) of
 * four taps at NDC (px, py): the receiver's depth there (its plane where it
 * comes nearer the light than P, else P's own depth; see the header) moved
 * by the bias towards the light. */
vec4 lixel_refs(LixelReceiver rcv, bool plane, vec4 px, vec4 py, float bias, bool greater)
{
  vec4 z = vec4(rcv.z);
  if (plane) {
    /* The receiver plane's depth on the light ray through each texel's
     * centre where the plane comes nearer the light than P; where it recedes
     * (or the ray passes its horizon and never meets it on the light's
     * side), P's own depth: nothing farther from the light than P can shadow
     * it, so a concave crease's other face, seen by the kernel's far taps,
     * is not taken for an occluder. */
    vec4 den = rcv.sigma.x * px + rcv.sigma.y * py + rcv.sigma.z;
    vec4 plane_z = (rcv.rho.x * px + rcv.rho.y * py + rcv.rho.z) / den;
    vec4 nearer = greater ? max(plane_z, z) : min(plane_z, z);
    z = mix(z, nearer, greaterThan(den * rcv.det, vec4(0.0)));  /* a select: no arithmetic on the others */
  }
  z += greater ? bias : -bias; /* towards the light */
  vec4 d = z * 0.5 + 0.5;
  return greater ? 1.0 - d : d;
}

/* 0 for the taps (keys `key` at NDC (px, py)) that saw past the receiver
 * plane yet nearer the light than P, 1 for the others. Such a tap's ray
 * missed P's receiver: the plane comes nearer the light there than what the
 * texel stored, so the receiver ends before that ray (a wall the light
 * grazes lies within a texel across, and its plane moves metres along the
 * light per texel step). What it saw is no part of the receiver and lies
 * between the plane's point and P along the light: it may or may not shade
 * P, so the PCF leaves the tap out and lets the taps that saw the receiver,
 * something nearer the light than its plane, or something behind P decide.
 * Counted lit, as the plane alone would have it, such taps put false-light
 * stripes on a shadowed wall 0.7 degrees from grazing (docs/papers.md,
 * "Grazing, session 23"). Both bounds are moved by the bias, so a tap on the
 * plane itself is always seen. */
vec4 lixel_seen(LixelReceiver rcv, bool plane, vec4 px, vec4 py, vec4 key, float bias, bool greater)
{
  if (!plane) {
    return vec4(1.0);
  }
  vec4 past = lixel_refs(rcv, true, px, py, -bias, greater);  /* the plane's (or P's) depth moved away from the light */
  vec4 before = lixel_refs(rcv, false, px, py, bias, greater); /* P's own depth moved towards it */
  return 1.0 - vec4(greaterThan(key, past)) * vec4(lessThan(key, before));
}

vec4 lixel_footprint_colour(float texels_per_pixel)
{
  float t = clamp(log2(max(texels_per_pixel, 1e-6)) / 4.0, -1.0, 1.0);
  return vec4(clamp(-t, 0.0, 1.0), 1.0 - abs(t), clamp(t, 0.0, 1.0), 1.0);
}

/* The one rule by which every filter (the PCF's taps, MDSM texels, the
 * revectorized runs) judges a tap: for keys `key` at NDC (px, py), 1 where
 * the key is nearer the light than the tap's reference (lixel_refs), and
 * `seen` 0 where the tap missed P's receiver (lixel_seen). A tap not seen
 * stands for what the taps seen say: the PCF divides by their weight (P is
 * lit where none is seen), and a revectorized run reads it as the PCF's
 * shadow rounded (lixel_revectorized). */
vec4 lixel_judge(LixelReceiver rcv, bool plane, vec4 px, vec4 py, vec4 key, float bias, bool greater, out vec4 seen)
{
  seen = lixel_seen(rcv, plane, px, py, key, bias, greater);
  return vec4(lessThan(key, lixel_refs(rcv, plane, px, py, bias, greater)));
}

/* Texel s of map m (at NDC p) judged: (its shadowed weight, its weight seen).
 * With n depths per texel, the n-shadow test's fraction (MDSM §4.2; the map
 * holds keys, smaller = nearer the light, channels beyond n repeat key 0),
 * and the texel is seen or missed as its key 0, the map's own depth on the
 * texel's ray: the other keys were met anywhere in its q x q neighbourhood
 * (mdsm_frag.glsl), and a key of the receiver itself from a texel beside it
 * lies past the plane on this ray wherever the plane moves more than the
 * bias per texel (judged each alone, they were left out: docs/papers.md,
 * "graze2, session 24"). */
vec2 lixel_texel(int m, ivec2 s, vec2 p, LixelReceiver rcv, bool plane, float bias, bool greater)
{
  vec4 t = lixel_fetch(m, s);
#ifdef LIXEL_MDSM
  vec4 key = t;
  const int n = LIXEL_MDSM;
#else
  vec4 key = vec4(greater ? 1.0 - t.r : t.r);
  const int n = 1;
#endif
  vec4 seen;
  vec4 shadowed = lixel_judge(rcv, plane, vec4(p.x), vec4(p.y), key, bias, greater, seen);
  float hits = 0.0;
  for (int j = 0; j < n; j++) {
    hits += shadowed[j];
  }
  return vec2(hits / float(n), 1.0) * seen.x;
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

/* The normal prepass_frag.glsl packed into the surface's fourth channel:
 * 14- and 15-bit octahedral coordinates in the bits of one float. */
vec2 lixel_unpack_normal(float code)
{
  uint v = floatBitsToUint(code);
  return (vec2(float((v >> 15) & 16383u), float(v & 32767u)) - vec2(8191.0, 16383.0)) / vec2(8191.0, 16383.0);
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

/* Tap i's weight along one axis of the k x k PCF kernel (taps i >= k weigh
 * nothing). Odd k: the k nearest texels alike (a box of k texels). Even k:
 * a box of k - 1 texels over the bilinearly interpolated test (Reeves et al.
 * 1987 with bilinear taps), the outer two taps weighed by the point's
 * fraction f of a texel past the first tap's centre; the shadow is then
 * continuous in the point's position. The weights of an axis sum to k (odd
 * k) or k - 1 (even k); the filter divides by the weight of the taps that saw
 * P's receiver (lixel_seen). */
float lixel_weight(int i, float f)
{
  const int k = LIXEL_PCF;
  if (i >= k) return 0.0;
  if (k % 2 == 1) return 1.0;
  return i == 0 ? 1.0 - f : (i == k - 1 ? f : 1.0);
}

/* The shadow tests (1 = shadowed) of the 2 x 2 texels c, c + 1 of map m, as
 * one gather: x = (c.x, c.y+1), y = (c.x+1, c.y+1), z = (c.x+1, c.y),
 * w = (c.x, c.y), clamped to the edge; each compared with its own reference
 * (lixel_refs). */
vec4 lixel_cell(int m, ivec2 c, LixelReceiver rcv, bool plane, float bias, bool greater, ivec2 size, out vec4 seen)
{
  vec2 to_ndc = 2.0 / vec2(size);
  vec4 t = lixel_gather(m, (vec2(c) + 1.0) / vec2(size));
  vec4 key = greater ? 1.0 - t : t;
  vec4 sx = clamp(vec4(c.x, c.x + 1, c.x + 1, c.x), 0.0, float(size.x - 1));
  vec4 sy = clamp(vec4(c.y + 1, c.y + 1, c.y, c.y), 0.0, float(size.y - 1));
  vec4 px = (sx + 0.5) * to_ndc.x - 1.0, py = (sy + 0.5) * to_ndc.y - 1.0;
  return lixel_judge(rcv, plane, px, py, key, bias, greater, seen);
}

#define LIXEL_REACH 4
/* Silhouette revectorization of the bilinear PCF 2 (Bondarev's shadow map
 * silhouette revectorization, 2014; Macedo and Apolinario, "Revectorization-
 * based shadow mapping", GI 2016, its cases): a straight shadow edge at a
 * shallow angle to a texel axis is stored as a staircase, runs of columns
 * split alike between two rows (near, far), and the bilinear filter follows
 * the stairs: up to half a texel from the edge across it. Each run ends where
 * the edge crosses one of its rows, at the middle between the run's last
 * column and the first one past it (within half a texel along the edge, a
 * fraction of that across it), so the edge is the line through the run's two
 * ends when they lie on opposite rows. P's cell (columns 0 and 1, taps
 * `first` and `second` as (near, far) along the strip `along`, P at fraction
 * f = (along, across)) is on a run when a column of it is split; a column not
 * split is then the run's end in the cell (a step of the stairs, at x = 0.5),
 * and up to LIXEL_REACH columns are read each way from the split ones.
 * A tap that missed P's receiver (lixel_judge) reads `fill`: what the taps
 * that saw it say of P, as in the PCF, whose division by their weight counts
 * each missed tap as their mean.
 * Returns (P's shadow: the bilinear ramp across the rows, one texel wide,
 * moved to that line; the run's length), or shadow -1 where the cell is not
 * on a run along this axis, an end is not found (a run longer than the
 * reach) or both lie on one row (a bump between two corners of a shadow). */
vec2 lixel_run(int m, ivec2 c, ivec2 along, vec2 first, vec2 second, vec2 f, LixelReceiver rcv, bool plane, float bias,
               bool greater, ivec2 size, float fill)
{
  bool split0 = first.x != first.y, split1 = second.x != second.y;
  if ((!split0 && !split1) || (split0 && split1 && first != second)) {
    return vec2(-1.0, 0.0);
  }
  float s = split0 ? first.x : second.x;
  vec2 run = vec2(s, 1.0 - s);
  /* The ends: x in cell units (column 0 at 0), and the row the edge crosses there (0 near, 1 far; -1 unknown). */
  float x0 = 0.5, x1 = 0.5;
  float row0 = split0 ? -1.0 : (first.x == s ? 1.0 : 0.0);
  float row1 = split1 ? -1.0 : (second.x == s ? 1.0 : 0.0);
  for (int j = 0; j < LIXEL_REACH / 2; j++) {
    for (int side = 0; side < 2; side++) {
      if ((side == 0 && !split0) || (side == 1 && !split1)) continue;
      int offset = side == 0 ? -2 * (j + 1) : 2 * (j + 1);
      vec4 seen;
      vec4 t = lixel_cell(m, c + offset * along, rcv, plane, bias, greater, size, seen);
      t = mix(vec4(fill), t, seen);  /* lixel_judge's rule */
      /* its two columns as (near, far), nearest P first: along x (z, y), (w, x) left, (w, x), (z, y) right */
      vec2 a = along.x == 1 ? t.wx : t.wz, b = along.x == 1 ? t.zy : t.xy;
      vec2 near = side == 0 ? b : a, far = side == 0 ? a : b;
      for (int k = 0; k < 2; k++) {
        vec2 col = k == 0 ? near : far;
        float x = side == 0 ? -0.5 - float(2 * j + k) : 1.5 + float(2 * j + k);
        bool open = side == 0 ? (split0 && x0 == 0.5) : (split1 && x1 == 0.5);
        if (open && col != run) {
          float row = col.x != col.y ? -2.0 : (col.x == s ? 1.0 : 0.0);
          if (side == 0) { x0 = x; row0 = row; } else { x1 = x; row1 = row; }
        }
      }
    }
  }
  if (row0 < 0.0 || row1 < 0.0 || row0 == row1) {
    return vec2(-1.0, 0.0);
  }
  float edge = clamp(mix(row0, row1, (f.x - x0) / (x1 - x0)), -0.5, 1.5);
  return vec2(clamp(0.5 + (s > 0.5 ? edge - f.y : f.y - edge), 0.0, 1.0), x1 - x0);
}

/* P's shadow with the edge revectorized (lixel_run) along whichever texel axis
 * the edge runs on the longer run, or `bilinear` (the PCF's) where it runs on
 * none; b, seen: the cell's taps (lixel_cell). The runs read binary tests, so
 * a tap that missed the receiver reads the PCF's shadow rounded. */
float lixel_revectorized(int m, ivec2 c, vec4 b, vec4 seen, vec2 f, float bilinear, LixelReceiver rcv, bool plane,
                         float bias, bool greater, ivec2 size)
{
  float fill = bilinear >= 0.5 ? 1.0 : 0.0;
  b = mix(vec4(fill), b, seen);
  vec2 across_y = lixel_run(m, c, ivec2(1, 0), b.wx, b.zy, f, rcv, plane, bias, greater, size, fill);
  vec2 across_x = lixel_run(m, c, ivec2(0, 1), b.wz, b.xy, f.yx, rcv, plane, bias, greater, size, fill);
  vec2 best = across_x.y > across_y.y ? across_x : across_y;
  return best.x >= 0.0 ? best.x : bilinear;
}

/* The shadow of P (normal N, light direction L) in map m, whose clip position
 * of P is h: the k x k PCF test with the bias above. */
float lixel_shadow(int m, vec3 P, vec3 N, vec3 L, vec4 h)
{
  vec4 info = lixel.maps[m].info;
  ivec2 size = ivec2(info.xy);
  vec2 tc = (h.xy / h.w * 0.5 + 0.5) * vec2(size);
  bool greater = lixel_greater(m);
  const bool plane_bias = LIXEL_BIAS == LIXEL_BIAS_RECEIVER_PLANE;
  const bool slope_bias = LIXEL_BIAS == LIXEL_BIAS_SLOPE || LIXEL_BIAS == LIXEL_BIAS_CONSTANT_SLOPE;
  vec3 NL = dot(N, L) < 0.0 ? -N : N; /* the receiver's side that faces the light */
  LixelReceiver rcv = lixel_receiver(m, P, NL, L, h, vec2(size), plane_bias, slope_bias);
  vec2 look = tc;
#if LIXEL_BIAS == LIXEL_BIAS_NORMAL_OFFSET
  /* Look up P moved s texel widths along its normal, towards the light. */
  vec3 Q = P + NL * (lixel.bias.y * rcv.width);
  vec4 hq = lixel.maps[m].matrix * vec4(Q, 1.0);
  look = (hq.xy / hq.w * 0.5 + 0.5) * vec2(size);
  rcv.z = lixel_stored_depth(m, Q, hq);
#endif
  float bias = 0.0;
#if LIXEL_BIAS != LIXEL_BIAS_NONE && LIXEL_BIAS != LIXEL_BIAS_SLOPE
  bias += lixel.bias.x * rcv.texel;
#endif
  if (slope_bias) {
    bias += lixel.bias.y * lixel.bias.z * rcv.slope;
  }
  bool plane = plane_bias && rcv.det != 0.0;
  float grazing = 0.0;  /* the plane's own error per texel of reach, in texels (below) */
  if (plane) {
    /* The plane's own error: a normal off by e radians moves the plane's
     * depth at a tap d texels across the light ray by d e / (n.l)^2 texels
     * along it (the derivative of d tan(alpha), n.l = cos(alpha)), which
     * passes any constant bias where the light grazes the receiver. Up to
     * the slope limit, as the SLOPE modes. */
    float ndl = max(dot(NL, L), 1e-6);
    grazing = LIXEL_NORMAL_ERROR / (ndl * ndl);
    bias += min(lixel.bias.z * grazing, LIXEL_SLOPE_LIMIT) * rcv.texel;
  }
  const int k = LIXEL_PCF;
  ivec2 base = (k % 2 == 1) ? ivec2(floor(look)) - (k - 1) / 2 : ivec2(floor(look - 0.5)) - (k / 2 - 1);
  vec2 f = fract(look - 0.5);  /* even k: the point's place between the first two taps' centres */
  vec2 to_ndc = 2.0 / vec2(size);
  float hits = 0.0, weights = 0.0;
#if defined(LIXEL_MDSM) || LIXEL_PCF == 1
  for (int dy = 0; dy < k; dy++) {
    for (int dx = 0; dx < k; dx++) {
      ivec2 s = clamp(base + ivec2(dx, dy), ivec2(0), size - 1);
      vec2 p = (vec2(s) + 0.5) * to_ndc - 1.0;
      vec2 t = lixel_texel(m, s, p, rcv, plane, bias, greater);
      float w = lixel_weight(dx, f.x) * lixel_weight(dy, f.y);
      hits += w * t.x;
      weights += w * t.y;
    }
  }
#else
  /* The k x k taps as 2 x 2 gathers (a gather costs about one texelFetch on
   * a software rasterizer; lixel_cell), the cell at c holding texels c and
   * c + 1 each way, each tap weighed by lixel_weight (taps beyond k - 1 weigh
   * nothing). */
  vec4 cell = vec4(0.0), seen = vec4(1.0);
  for (int gy = 0; gy < k; gy += 2) {
    for (int gx = 0; gx < k; gx += 2) {
      cell = lixel_cell(m, base + ivec2(gx, gy), rcv, plane, bias, greater, size, seen);
      vec2 wx = vec2(lixel_weight(gx, f.x), lixel_weight(gx + 1, f.x));
      vec2 wy = vec2(lixel_weight(gy, f.y), lixel_weight(gy + 1, f.y));
      vec4 w = vec4(wx.x * wy.y, wx.y * wy.y, wx.y * wy.x, wx.x * wy.x) * seen;
      hits += dot(w, cell);
      weights += dot(w, vec4(1.0));
    }
  }
#endif
  /* over the taps that saw P's receiver (lixel_seen); a missed tap is lit, so none seen: lit */
  float shadow = weights > 0.0 ? hits / weights : 0.0;
#if LIXEL_PCF == 2 && !defined(LIXEL_MDSM) && defined(LIXEL_REVECTORIZE)
  if (shadow > 0.0 && shadow < 1.0) {
    /* its taps reach LIXEL_REACH texels farther: the plane's error there too */
    float reach_bias = bias + min(float(LIXEL_REACH) * grazing, LIXEL_SLOPE_LIMIT) * rcv.texel;
    shadow = lixel_revectorized(m, base, cell, seen, f, shadow, rcv, plane, reach_bias, greater, size);
  }
#endif
#ifdef LIXEL_REGIONS
  /* A plane map (a map with a region) at one lixel per pixel samples each
   * pixel's own point of its plane (Chong-Gortler §2): the test of that one
   * lixel is the exact shadow there, and the k x k taps would only blur it
   * over k pixels. Below one lixel per pixel (s < 1) the points fall between
   * lixels, and the taps reconstruct the shadow as in any map. */
  vec2 off_centre = abs(fract(tc) - 0.5);
  if (lixel.maps[m].range.w > 0.5 && max(off_centre.x, off_centre.y) <= LIXEL_ON_LIXEL) {
    ivec2 own = ivec2(floor(tc));
    vec2 p = (vec2(own) + 0.5) * to_ndc - 1.0;
    vec2 t = lixel_texel(m, own, p, rcv, plane, bias, greater);
    shadow = t.y > 0.0 ? t.x / t.y : 0.0;
  }
#endif
  return shadow;
}

void main()
{
  /* The surface the pre-pass saw here (prepass_frag.glsl); this pass runs only
   * where it saw one (a full-screen triangle on the far plane, GREATER). */
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 surface = texelFetch(u_surface, px, 0);
#ifdef LIXEL_HOLDOUT
  if (surface.w < 0.0) {
#  if defined(LIXEL_SHADOW_ALPHA) || defined(LIXEL_BLURRED)
    out_color = vec4(0.0, 0.0, 0.0, -1.0);
#  else
    out_color = vec4(0.0);
#  endif
#  ifdef LIXEL_FOOTPRINT
    out_footprint = vec4(0.0, 0.0, 0.0, 1.0);
#  endif
#  ifdef LIXEL_DATA
    out_data = vec4(0.0, 0.0, 0.0, dot(lixel.eye_row, vec4(surface.xyz, 1.0)));   /* - eye depth */
#  endif
#  ifdef LIXEL_WORLD
    out_world = vec4(0.0);
#  endif
    return;
  }
#endif
  vec3 P = surface.xyz;
  vec3 N = lixel_unoctahedral(lixel_unpack_normal(surface.w));
  /* The pre-pass's normal (screen derivatives) faces the viewer, unless the camera is mirrored (scaled negatively,
   * itself or by a parent): then it faces away, and the side seen, which Blender's engines light, is -N. */
  N = lixel.view_dir.w < 0.0 ? -N : N;
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
#ifdef LIXEL_UNLIT
  bool lit = (floatBitsToUint(surface.w) & 0x40000000u) != 0u;
#else
  const bool lit = true;
#endif
  float shadow = 0.0;
  if (index >= 0 && lit) {
    shadow = lixel_shadow(m, P, N, L, hsel);
#ifdef LIXEL_BLENDS
    /* A cascade's seam (addon/warp/methods/cascade.py): a map whose blend band
     * (extra.y) reaches past the end of its depth range still holds P there,
     * and across that band the shadow fades from it into P's own map. */
    for (int j = 0; j < index; j++) {
      float past = eye_depth - lixel.maps[j].range.y;
      float band = lixel.maps[j].extra.y;
      if (band <= 0.0 || past <= 0.0 || past >= band) continue;
      vec4 hj = lixel.maps[j].matrix * vec4(P, 1.0);
      if (hj.w <= 0.0 || any(greaterThan(abs(hj.xyz / hj.w), vec3(1.0)))) continue;
      shadow = mix(lixel_shadow(j, P, N, L, hj), shadow, past / band);
      break;
    }
#endif
  }

  float ndl = lit ? max(dot(N, L), 0.0) : 0.0;
  vec3 direct = lixel.light_color.rgb * (irradiance * ndl * lixel.light_color.w / LIXEL_PI);

#ifdef LIXEL_BLURRED
  out_color = vec4(direct, 1.0);
#else
  out_color = vec4(direct * (1.0 - shadow) + lixel.ambient.rgb * lixel.light_color.w, 1.0);
#endif
#ifdef LIXEL_SHADOW_ALPHA
  out_color.a = shadow;
#endif
#ifdef LIXEL_FOOTPRINT
  out_footprint = lixel_footprint_colour(texels_per_pixel);
#endif
#ifdef LIXEL_DATA
  out_data = vec4(lit ? shadow : -1.0, float(index), texels_per_pixel, eye_depth);   /* -1: unlit */
#endif
#ifdef LIXEL_WORLD
  out_world = vec4(P, surface.w);
#endif
}
