// csm.glsl: ray / heightfield intersection in texture space (GLSL 330 core).
//
// Included after "#version 330 core" and the defines below; see csm_assets.render.
//
// The ray (Dummer's convention): it starts on the polygon at texture coordinate
// dp, at height 1 (the top of the relief), and moves along the unit vector ds with
// ds.z >= 0 pointing down:  uv(sc) = dp + ds.xy * sc,  height(sc) = 1 - ds.z * sc.
// Heights come from the step map's R channel; G = sqrt(cone ratio / max_ratio).
// Every fetch of the march reads one explicit level (textureLod at csm_lod, 0: the map itself),
// so a sampler with mipmaps (an engine's own, averaged: their cones are not safe) never moves
// the surface the march sees; shading fetches at the hit are the caller's (surface_frag.glsl
// filters them over the pixel's visible footprint: textureGrad with csm_shading_grads' gradients).
//
// Every function returns a CsmHit: the ray parameter sc of the hit, the number of
// iterations (texture steps) it took, and a status:
//   CSM_HIT   converged (the ray reached the surface, or a fixed method ended)
//   CSM_CAP   stopped by the iteration cap (horizontal or very grazing rays)
//   CSM_MISS  the ray left a non-tiled texture before reaching the surface
//
// Guards the paper leaves open: a ray parallel to the surface never ends its
// _exact loop (capped by max_iterations); a cone ratio of 0 divides by zero
// (the step is written as above * ratio / (ds.z * ratio + iz) with a floor on
// the denominator); rays leaving a non-tiled texture stop as CSM_MISS.
//
// Defines (set at load time):
//   CSM_FIXED_STEPS  the unrolled step count of intersect_cone_fixed (1..127)
//   CSM_QUADRANT_MAPS  the map is a quadrant map (two images: stepmap = (h, c0, c1, c2),
//                    stepmap2 = (h, c3, B, A)); shadows read their quadrant's cone, normals stepmap2
//   CSM_MAX_ACROSS   the minimum step along a steep ray is at most this many times the minimum step
//   CSM_LEVEL_MIN_STEP  the least minimum step, in texels of the marched level, above level 0
//   CSM_LEVEL_ACROSS, CSM_LEVEL_MAX_STEP  above level 0 the exact march's minimum step also crosses
//                    CSM_LEVEL_ACROSS texels of the marched level, at most CSM_LEVEL_MAX_STEP along the ray

#ifndef CSM_FIXED_STEPS
#define CSM_FIXED_STEPS 10
#endif

#define CSM_HIT 0
#define CSM_CAP 1
#define CSM_MISS 2

uniform sampler2D stepmap;   // RGBA step map, LINEAR filtering (mipmaps or not), REPEAT when tiled
uniform sampler2D stepmap2;  // quadrant maps' second image (R height, G cone of +u-v, B/A slopes)
uniform float max_ratio;     // the cone ratio that G = 1 stands for
uniform bvec2 tiled;         // per axis u, v; false: rays that leave uv in [0, 1] miss
uniform int conesteps;       // _loop steps, the linear steps of pom / relief, relaxed's search steps
uniform int binary_steps;    // relief mapping's binary search steps
uniform int max_iterations;  // the cap of _exact
uniform float min_step;      // the minimum step of _exact, relaxed and shadows in texels (the paper: 1;
                             // materials hold (0, 1]; clamped to [1e-3, CSM_MAX_MIN_STEP])

uniform int levels;          // levels of the step map's chain above level 0 that the march may use
                             // (csm_march_lod; 0, a map without a chain: the march reads level 0)

// The level every march fetch reads (textureLod). Set once per pixel, before the intersection,
// by csm_lod = csm_march_lod(dFdx(uv), dFdy(uv)); an engine that never sets it marches level 0.
float csm_lod = 0.0;

// log2 of the polygon's footprint's shorter axis in level-0 texels, from its uv change per pixel
// across and down the screen (duv_dx, duv_dy): what the level, the shading taps' spread and the
// pixel quad's share are chosen by.
float csm_footprint_octaves(vec2 duv_dx, vec2 duv_dy)
{
    vec2 size = vec2(textureSize(stepmap, 0));
    return log2(max(min(length(duv_dx * size), length(duv_dy * size)), 1e-30));
}

// The level a pixel marches on, from its uv footprint (duv_dx, duv_dy: the uv's change per pixel
// across and down the screen, taken in uniform control flow): the footprint's shorter axis in
// level-0 texels, one level finer than the footprint, floor(log2(texels)) - 1, clamped to
// 0..levels (an integer: textureLod reads that level alone). 0 without a chain (levels == 0) and
// at up to 4 texels a pixel, so near the camera the march is level 0's. The chain's levels carry
// their own exact cones (csm_assets.step_levels); averaged mipmaps an engine makes itself are
// never marched (levels stays 0: their cones are not safe for the surface they average).
float csm_march_lod(vec2 duv_dx, vec2 duv_dy)
{
    if (levels <= 0)
        return 0.0;
    return clamp(floor(csm_footprint_octaves(duv_dx, duv_dy)) - 1.0, 0.0, float(levels));
}

#ifndef CSM_FAR_SHARPEN
#define CSM_FAR_SHARPEN 0.5  // levels finer per octave beyond 8 texels a pixel (csm_shading_grads)
#endif

// The gradients every shading fetch at the hit takes, textureGrad(map, uv, duv_dx, duv_dy) after
// this replaces them: an isotropic footprint (the axis g and g turned a right angle in the step
// map's texels, so GL's level and an anisotropic sampler's are both log2 of g's texels; g twice
// would be a footprint of no area, which an anisotropic sampler reads at level 0) whose axis is
// the shorter of the pixel's visible footprint, from the polygon's (duv_dx, duv_dy, as
// csm_march_lod takes them) and the ray ds. A ray started v further along the polygon meets the
// surface's plane at the hit (its slope grad h: the stored slopes filtered over the polygon
// footprint's shorter axis) v - ds.xy * dot(grad h, v) / (ds.z + dot(grad h, ds.xy)) further on:
// a wall facing the eye narrows the footprint, a slope turned away widens it (the divisor is held
// at 0.1 ds.z or more). Filtering the polygon's longer axis averages grooves and walls the pixel
// does not see (docs/measurements/distance.md); at a texel a pixel or less this reads level 0
// (one bilinear sample) but where a slope turned away widens it. Beyond 8 texels a pixel along
// the polygon's shorter axis the footprint shrinks CSM_FAR_SHARPEN of a level per octave (two
// octaves at most: half a level finer at 16 texels, one at 32): the farther, the more of the
// relief under a pixel is hidden, and a footprint-sized average takes it in (brighter or darker
// than what the pixel sees); up to 8 texels a pixel nothing changes.
void csm_shading_grads(vec2 uv, vec3 ds, inout vec2 duv_dx, inout vec2 duv_dy)
{
    vec2 size = vec2(textureSize(stepmap, 0));
    vec2 g = length(duv_dx * size) < length(duv_dy * size) ? duv_dx : duv_dy;
    float far = clamp(log2(max(length(g * size), 1e-30)) - 3.0, 0.0, 2.0);  // octaves beyond 8 texels
#ifdef CSM_QUADRANT_MAPS
    vec4 t = textureGrad(stepmap2, uv, g, g);  // the second image holds the slopes
#else
    vec4 t = textureGrad(stepmap, uv, g, g);
#endif
    vec2 slope = vec2(t.b - 0.5, 0.5 - t.a) * size;  // dh/du, dh/dv (v down the image)
    float below = max(ds.z + dot(slope, ds.xy), max(0.1 * ds.z, 1e-6));
    vec2 ax = duv_dx - ds.xy * (dot(slope, duv_dx) / below);
    vec2 ay = duv_dy - ds.xy * (dot(slope, duv_dy) / below);
    duv_dx = (length(ax * size) < length(ay * size) ? ax : ay) * exp2(-CSM_FAR_SHARPEN * far);
    duv_dy = vec2(-duv_dx.y * size.y, duv_dx.x * size.x) / size;
}

#ifndef CSM_NORMAL_SHARPEN
#define CSM_NORMAL_SHARPEN 0.5  // near: levels finer than the shading footprint the lit normal is fetched at
#endif

#ifndef CSM_TAP_SPREAD
#define CSM_TAP_SPREAD 0.25  // far away: the visible taps' distance from the hit along each footprint axis
#endif
#ifndef CSM_TAP_SHRINK
#define CSM_TAP_SHRINK 0.5  // far away: each visible tap's footprint, in the shading footprint's
#endif

#ifndef CSM_QUAD_SHARE
#define CSM_QUAD_SHARE 0.2
#endif
#ifndef CSM_QUAD_SHARE_FAR
#define CSM_QUAD_SHARE_FAR 0.2
#endif

// How far the shading taps spread (csm_visible_taps), from the polygon's footprint (duv_dx,
// duv_dy, as csm_march_lod takes them): 0 at 2 texels a pixel or fewer along its shorter axis
// (one fetch: the shading near is one hit's), rising to 1 at 4. csm_quad_weight ramps with it.
float csm_tap_spread(vec2 duv_dx, vec2 duv_dy)
{
    return clamp(csm_footprint_octaves(duv_dx, duv_dy) - 1.0, 0.0, 1.0);
}

// The share of a pixel's shaded colour its two neighbours in its 2x2 pixel quad (across and down)
// take far away, from the polygon's footprint (duv_dx, duv_dy, as csm_march_lod takes them): 0 at
// 2 texels a pixel or fewer along its shorter axis (near, the picture is one hit's), rising to
// CSM_QUAD_SHARE at 4, held to 8, then to CSM_QUAD_SHARE_FAR at 16 or more. Far away, one hit a
// pixel jumps between a brick's top and the mortar as the camera moves; the share hides it
// (docs/measurements/distance.md).
float csm_quad_weight(vec2 duv_dx, vec2 duv_dy)
{
    float octaves = csm_footprint_octaves(duv_dx, duv_dy);
    return mix(CSM_QUAD_SHARE, CSM_QUAD_SHARE_FAR, clamp(octaves - 3.0, 0.0, 1.0))
           * clamp(octaves - 1.0, 0.0, 1.0);  // csm_tap_spread's ramp
}

// c blended with its quad's neighbours across and down, each weighted w (pixel quad message
// passing, Penner 2011): dFdx and dFdy of c are those neighbours' differences where derivatives
// are taken per pixel (fine, as llvmpipe's); coarse ones (per quad) blend a little less exactly.
// Call it in uniform control flow, with the colour every pixel of the quad computes.
vec3 csm_quad_share(vec3 c, float w)
{
    vec2 side = 1.0 - 2.0 * mod(floor(gl_FragCoord.xy), 2.0);  // +1: the neighbour is at +x (+y)
    return c + w * (side.x * dFdx(c) + side.y * dFdy(c));
}

// Four shading fetches around the hit, each weighted by how much of it the pixel sees, in place
// of one filtered fetch (csm_visible_taps, csm_tapped). A filtered fetch weighs every texel of
// its footprint alike; the pixel sees a patch of the surface in proportion to its area projected
// towards the eye, ds.z + dot(grad h, ds.xy) per unit of uv (the rays' density on a plane of
// slope grad h, csm_shading_grads' divisor), so a wall facing the eye counts more and a slope
// turned away not at all. On a deep weave far away one filtered fetch was 1.02-1.3 times as far
// from the supersampled picture as one unfiltered sample; the weighted taps, 0.69-0.97 times
// (docs/measurements/distance.md).
struct CsmTaps {
    vec4 w;        // the taps' weights, summing to 1
    vec2 a, b;     // tap i at the hit + (-a, +a, -a, +a)[i] + (-b, -b, +b, +b)[i]
    vec2 dx, dy;   // each tap's gradients (textureGrad)
    vec2 slope;    // the stored slopes (B - 0.5, 0.5 - A) with the same weights, for the lit normal
    bool single;   // near: one fetch at the hit (w = (1, 0, 0, 0), a = b = 0)
};

vec2 csm_tap_slope(vec2 uv, vec2 dx, vec2 dy)
{
#ifdef CSM_QUADRANT_MAPS
    vec4 t = textureGrad(stepmap2, uv, dx, dy);  // the second image holds the slopes
#else
    vec4 t = textureGrad(stepmap, uv, dx, dy);
#endif
    return vec2(t.b - 0.5, 0.5 - t.a);
}

// The taps of a hit at uv of the ray ds, in the shading footprint (dx, dy: csm_shading_grads')
// spread by spread (csm_tap_spread): far away tap i CSM_TAP_SPREAD of the footprint from the hit
// along each axis, its footprint CSM_TAP_SHRINK of it, weighted by its projected area max(ds.z +
// dot(grad h, ds.xy), 0) from its own slopes (alike where no tap faces the eye); near (spread 0)
// one tap at the hit. The slopes, which the lit normal takes weighted, are fetched finer than the
// colour: CSM_NORMAL_SHARPEN of a level near, CSM_TAP_SHRINK's level far away (N·L of an averaged
// normal is not the average of N·L: the relief lights flatter than its texels do; a finer fetch
// keeps the slopes a footprint averages apart longer). Four fetches of the step map far away, one
// near.
CsmTaps csm_visible_taps(vec2 uv, vec3 ds, vec2 dx, vec2 dy, float spread)
{
    CsmTaps k;
    k.single = spread <= 0.0;
    k.a = dx * (CSM_TAP_SPREAD * spread);
    k.b = dy * (CSM_TAP_SPREAD * spread);
    k.dx = dx * mix(1.0, CSM_TAP_SHRINK, spread);
    k.dy = dy * mix(1.0, CSM_TAP_SHRINK, spread);
    float fine = mix(exp2(-CSM_NORMAL_SHARPEN), CSM_TAP_SHRINK, spread);
    if (k.single) {
        k.w = vec4(1.0, 0.0, 0.0, 0.0);
        k.slope = csm_tap_slope(uv, dx * fine, dy * fine);
        return k;
    }
    vec2 size = vec2(textureSize(stepmap, 0));
    vec2 s0 = csm_tap_slope(uv - k.a - k.b, dx * fine, dy * fine);
    vec2 s1 = csm_tap_slope(uv + k.a - k.b, dx * fine, dy * fine);
    vec2 s2 = csm_tap_slope(uv - k.a + k.b, dx * fine, dy * fine);
    vec2 s3 = csm_tap_slope(uv + k.a + k.b, dx * fine, dy * fine);
    vec4 w = max(ds.z + vec4(dot(s0 * size, ds.xy), dot(s1 * size, ds.xy), dot(s2 * size, ds.xy),
                             dot(s3 * size, ds.xy)), 0.0);
    float total = w.x + w.y + w.z + w.w;
    k.w = total > 1e-12 ? w / total : vec4(0.25);
    k.slope = k.w.x * s0 + k.w.y * s1 + k.w.z * s2 + k.w.w * s3;
    return k;
}

// A map fetched at the taps k around uv (the map's own uv at the hit); to_map turns the step
// map's uv offsets and gradients into the map's (identity where the map shares the step map's uvs).
vec4 csm_tapped(sampler2D map, CsmTaps k, vec2 uv, mat2 to_map)
{
    vec2 dx = to_map * k.dx, dy = to_map * k.dy;
    if (k.single)
        return textureGrad(map, uv, dx, dy);
    vec2 a = to_map * k.a, b = to_map * k.b;
    return k.w.x * textureGrad(map, uv - a - b, dx, dy) + k.w.y * textureGrad(map, uv + a - b, dx, dy)
         + k.w.z * textureGrad(map, uv - a + b, dx, dy) + k.w.w * textureGrad(map, uv + a + b, dx, dy);
}

struct CsmHit {
    float sc;
    int iterations;
    int status;
};

float csm_texel()  // the paper's minimum feature size, 1 / texsize of the marched level (csm_lod)
{
    ivec2 size = textureSize(stepmap, int(csm_lod));
    return 1.0 / float(max(size.x, size.y));
}

#ifndef CSM_MAX_MIN_STEP
#define CSM_MAX_MIN_STEP 16.0  // texels; above 1 only for benchmarks/relaxed_trade.py's sweep
#endif

float csm_min_step()  // the minimum step in uv: min_step texels of the marched level, clamped
{
    return csm_texel() * clamp(min_step, 1e-3, CSM_MAX_MIN_STEP);
}

bool csm_outside(vec2 uv)
{
    bvec2 out_ = bvec2(uv.x < 0.0 || uv.x > 1.0, uv.y < 0.0 || uv.y > 1.0);
    return (out_.x && !tiled.x) || (out_.y && !tiled.y);
}

// The ray parameter where the ray leaves uv in [0, 1] through a non-tiled side
// (a large number when it never does).
float csm_exit(vec2 dp, vec3 ds)
{
    float e = 3.0e38;
    if (!tiled.x && ds.x != 0.0)
        e = min(e, ((ds.x > 0.0 ? 1.0 : 0.0) - dp.x) / ds.x);
    if (!tiled.y && ds.y != 0.0)
        e = min(e, ((ds.y > 0.0 ? 1.0 : 0.0) - dp.y) / ds.y);
    return max(e, 0.0);
}

// A step that crossed a non-tiled side: did the ray reach the surface before it?
bool csm_under_at_exit(vec2 dp, vec3 ds, float edge)
{
    return 1.0 - ds.z * edge <= textureLod(stepmap, dp + ds.xy * edge, csm_lod).r;
}

// The largest step that stays inside the cone of the texel under the ray:
// above = height of the ray over the surface there, g = the G channel.
float csm_cone_step(float above, float g, vec3 ds, float iz)
{
    float ratio = g * g * max_ratio;
    return above * ratio / max(ds.z * ratio + iz, 1e-30);
}

#ifndef CSM_MAX_ACROSS
#define CSM_MAX_ACROSS 8.0
#endif

#ifndef CSM_LEVEL_MIN_STEP
#define CSM_LEVEL_MIN_STEP 1.5  // texels of the marched level: the least minimum step above level 0
#endif
#ifndef CSM_LEVEL_ACROSS
#define CSM_LEVEL_ACROSS 0.75  // texels of the marched level the exact march's minimum step crosses above level 0
#endif
#ifndef CSM_LEVEL_MAX_STEP
#define CSM_LEVEL_MAX_STEP 3.0  // texels of the marched level: CSM_LEVEL_ACROSS's step along the ray at most
#endif

// The quadrant of a ray's direction in uv (v down the image): 0 +u+v, 1 -u+v, 2 -u-v, 3 +u-v
// (csm_assets.quadrant_cone_ratios' order; a ray along an axis may take either side's quadrant,
// since each quadrant includes its two axes).
int csm_quadrant(vec3 ds)
{
    return ds.x >= 0.0 ? (ds.y >= 0.0 ? 0 : 3) : (ds.y >= 0.0 ? 1 : 2);
}

// (height, cone channel) at uv with one fetch: q = -1 or 0 the first image's G; on a quadrant
// map q = 1, 2 its B, A and q = 3 the second image's G.
vec2 csm_fetch(vec2 uv, int q)
{
    if (q == 3)
        return textureLod(stepmap2, uv, csm_lod).rg;
    vec4 t = textureLod(stepmap, uv, csm_lod);
    return vec2(t.r, q == 1 ? t.b : (q == 2 ? t.a : t.g));
}

// The cone channel the shadows of this map read for a ray going ds (-1: the only one)
int csm_map_quadrant(vec3 ds)
{
#ifdef CSM_QUADRANT_MAPS
    return csm_quadrant(ds);
#else
    return -1;
#endif
}

// The cone march of _exact and quadrant: cone steps plus a minimum step until a sample lies
// under the surface. Cones of channel q (csm_fetch). paper: the paper's end (a minimum step of
// min_step texels along the 3D ray, and the hit backs off that step); else the minimum step is
// min_step texels across the texture (w / |ds.xy|, at most CSM_MAX_ACROSS times w along the ray:
// steep rays no longer crawl), and the hit is the interpolated crossing between the last point
// above and the first under, clamped to the last minimum step (no fetch). On a level of the
// chain (csm_lod > 0, far away) the minimum step is CSM_LEVEL_MIN_STEP texels of that level at
// least (a level-k texel is a quarter to a half of the pixel's footprint, csm_march_lod), and
// with the paper's end a step that crosses CSM_LEVEL_ACROSS of those texels of the texture (at
// most CSM_LEVEL_MAX_STEP of them along the ray) when that is longer: the march no longer crawls
// up to the surface in steps much finer than the pixel sees (steep rays crawled most: 1.5 texels
// along a ray 45 degrees down through relief 0.1 deep cross a seventh of a texel).
// Guards: capped by max_iterations (horizontal rays), the cone step's floor on its denominator
// (zero cones), CSM_MISS past a non-tiled side.
CsmHit csm_cone_march(vec2 dp, vec3 ds, int q, bool paper)
{
    float w = csm_min_step();
    if (csm_lod > 0.0) {
        w = max(w, csm_texel() * CSM_LEVEL_MIN_STEP);
        if (paper)
            w = max(w, csm_texel() * min(CSM_LEVEL_ACROSS / max(length(ds.xy), 1e-6), CSM_LEVEL_MAX_STEP));
    }
    if (!paper)
        w /= max(length(ds.xy), 1.0 / CSM_MAX_ACROSS);
    float iz = sqrt(max(0.0, 1.0 - ds.z * ds.z));
    float sc = 0.0;
    float prev = 0.0;
    float a_prev = 0.0;
    vec2 t = csm_fetch(dp, q);
    int i = 0;
    while (true) {
        float above = 1.0 - ds.z * sc - t.x;
        if (above <= 0.0) {
            if (i == 0 || paper)
                return CsmHit(i > 0 ? sc - w : sc, i, CSM_HIT);
            float x = mix(prev, sc, clamp(a_prev / max(a_prev - above, 1e-30), 0.0, 1.0));
            return CsmHit(clamp(x, max(sc - w, prev), sc), i, CSM_HIT);
        }
        if (i >= max_iterations)
            return CsmHit(sc, i, CSM_CAP);
        prev = sc;
        a_prev = above;
        sc += w + csm_cone_step(above, t.y, ds, iz);
        ++i;
        if (csm_outside(dp + ds.xy * sc)) {  // crossed a side: a hit only if under at the side
            float edge = csm_exit(dp, ds);
            if (csm_under_at_exit(dp, ds, edge))
                return CsmHit(min(sc - w, edge), i, CSM_HIT);
            return CsmHit(edge, i, CSM_MISS);
        }
        t = csm_fetch(dp + ds.xy * sc, q);
    }
    return CsmHit(sc, i, CSM_CAP);  // not reached
}

// slowest, but best quality: steps until it hits, plus a minimum step each time
// (one texel in the paper, min_step texels here), then backs off that step (_exact)
CsmHit intersect_cone_exact(vec2 dp, vec3 ds)
{
    return csm_cone_march(dp, ds, -1, true);
}

// _exact with the new end of the march (csm_cone_march: the minimum step across the texture,
// the interpolated crossing), on a conservative map: measured beside exact and quadrant
CsmHit intersect_cone_exact_interp(vec2 dp, vec3 ds)
{
    return csm_cone_march(dp, ds, -1, false);
}

// _exact on a quadrant map: the ray reads the cone of its own quadrant, one fetch per step
// (csm_assets.quadrant_cone_ratios: on average about twice as wide as the conservative cone)
CsmHit intersect_cone_quadrant(vec2 dp, vec3 ds)
{
    return csm_cone_march(dp, ds, csm_quadrant(ds), false);
}

// relaxed cone stepping (Policarpo and Oliveira, GPU Gems 3 ch. 18) on a map of relaxed
// cones (csm_assets.relaxed_cone_ratios; conservative cones work too, narrower): cone steps
// plus min_step texels until a sample lies under the surface (a relaxed cone lets the ray
// enter the surface once, never leave it), then conesteps steps of a bracketed secant search
// (Illinois: regula falsi that halves a stale end's value) between the last point above and
// the first below, and a last interpolation between them (no fetch). The guards of _exact:
// capped by max_iterations, the cone step's floor on its denominator, CSM_MISS past a
// non-tiled side.
CsmHit intersect_cone_relaxed(vec2 dp, vec3 ds)
{
    float w = csm_min_step();
    float iz = sqrt(max(0.0, 1.0 - ds.z * ds.z));
    float lo = 0.0;
    float sc = 0.0;
    vec4 t = textureLod(stepmap, dp, csm_lod);
    float above = 1.0 - t.r;
    float a_lo = above;
    int i = 0;
    while (above > 0.0) {
        if (i >= max_iterations)
            return CsmHit(sc, i, CSM_CAP);
        lo = sc;
        a_lo = above;
        sc += w + csm_cone_step(above, t.g, ds, iz);
        ++i;
        if (csm_outside(dp + ds.xy * sc)) {  // crossed a side: search up to it if under there
            float edge = csm_exit(dp, ds);
            if (!csm_under_at_exit(dp, ds, edge))
                return CsmHit(edge, i, CSM_MISS);
            sc = edge;
            above = 1.0 - ds.z * sc - textureLod(stepmap, dp + ds.xy * sc, csm_lod).r;
            break;
        }
        t = textureLod(stepmap, dp + ds.xy * sc, csm_lod);
        above = 1.0 - ds.z * sc - t.r;
    }
    if (i == 0)
        return CsmHit(sc, 0, CSM_HIT);
    float hi = sc;
    float a_hi = min(above, 0.0);
    int n = max(conesteps, 0);
    int side = 0;
    for (int k = 0; k < n; ++k) {
        float mid = mix(lo, hi, clamp(a_lo / max(a_lo - a_hi, 1e-30), 0.0, 1.0));
        float a = 1.0 - ds.z * mid - textureLod(stepmap, dp + ds.xy * mid, csm_lod).r;
        if (a <= 0.0) {
            hi = mid; a_hi = a;
            if (side == -1) a_lo *= 0.5;
            side = -1;
        } else {
            lo = mid; a_lo = a;
            if (side == 1) a_hi *= 0.5;
            side = 1;
        }
    }
    return CsmHit(mix(lo, hi, clamp(a_lo / max(a_lo - a_hi, 1e-30), 0.0, 1.0)), i + n, CSM_HIT);
}

// Status of the cone-only variants: still moving by more than a texel = not converged.
int csm_cone_status(vec2 dp, vec3 ds, float sc, float last_step)
{
    if (csm_outside(dp + ds.xy * sc))
        return CSM_MISS;
    return last_step > csm_texel() ? CSM_CAP : CSM_HIT;
}

// pretty fast: a uniform number of cone steps (the paper's _loop)
CsmHit intersect_cone_loop(vec2 dp, vec3 ds)
{
    float iz = sqrt(max(0.0, 1.0 - ds.z * ds.z));
    float sc = 0.0;
    float step = 0.0;
    int i = 0;
    for (; i < conesteps; ++i) {
        if (csm_outside(dp + ds.xy * sc))
            break;
        vec4 t = textureLod(stepmap, dp + ds.xy * sc, csm_lod);
        step = csm_cone_step(max(1.0 - ds.z * sc - t.r, 0.0), t.g, ds, iz);
        sc += step;
    }
    return CsmHit(sc, i, csm_cone_status(dp, ds, sc, step));
}

// the super fast version: CSM_FIXED_STEPS cone steps, unrolled by the
// preprocessor, no branches (the paper's _fixed)
#define CSM_FIXED_STEP \
    t = textureLod(stepmap, dp + ds.xy * sc, csm_lod); \
    step = csm_cone_step(max(1.0 - ds.z * sc - t.r, 0.0), t.g, ds, iz); \
    sc += step;
#define CSM_FIXED_STEP2 CSM_FIXED_STEP CSM_FIXED_STEP
#define CSM_FIXED_STEP4 CSM_FIXED_STEP2 CSM_FIXED_STEP2
#define CSM_FIXED_STEP8 CSM_FIXED_STEP4 CSM_FIXED_STEP4
#define CSM_FIXED_STEP16 CSM_FIXED_STEP8 CSM_FIXED_STEP8
#define CSM_FIXED_STEP32 CSM_FIXED_STEP16 CSM_FIXED_STEP16
#define CSM_FIXED_STEP64 CSM_FIXED_STEP32 CSM_FIXED_STEP32

CsmHit intersect_cone_fixed(vec2 dp, vec3 ds)
{
    float iz = sqrt(max(0.0, 1.0 - ds.z * ds.z));
    float sc = 0.0;
    float step = 0.0;
    vec4 t;
#if (CSM_FIXED_STEPS / 64) % 2 == 1
    CSM_FIXED_STEP64
#endif
#if (CSM_FIXED_STEPS / 32) % 2 == 1
    CSM_FIXED_STEP32
#endif
#if (CSM_FIXED_STEPS / 16) % 2 == 1
    CSM_FIXED_STEP16
#endif
#if (CSM_FIXED_STEPS / 8) % 2 == 1
    CSM_FIXED_STEP8
#endif
#if (CSM_FIXED_STEPS / 4) % 2 == 1
    CSM_FIXED_STEP4
#endif
#if (CSM_FIXED_STEPS / 2) % 2 == 1
    CSM_FIXED_STEP2
#endif
#if CSM_FIXED_STEPS % 2 == 1
    CSM_FIXED_STEP
#endif
    return CsmHit(sc, CSM_FIXED_STEPS, csm_cone_status(dp, ds, sc, step));
}

// parallax mapping with offset limiting (Welsh): one lookup, the offset is the
// depth under the top along the unit view vector (never more than that depth)
CsmHit intersect_parallax(vec2 dp, vec3 ds)
{
    float sc = 1.0 - textureLod(stepmap, dp, csm_lod).r;
    return CsmHit(sc, 1, csm_outside(dp + ds.xy * sc) ? CSM_MISS : CSM_HIT);
}

// The linear search of steep parallax / POM / relief: conesteps equal layers of
// height from the top to the bottom. Returns the first layer under the surface
// in hit.sc (prev_sc: the layer before it) or the status where it stopped.
CsmHit csm_linear_search(vec2 dp, vec3 ds, out float prev_sc)
{
    int n = max(conesteps, 1);
    float dsc = 1.0 / (float(n) * max(ds.z, 1e-6));
    float sc = 0.0;
    prev_sc = 0.0;
    for (int i = 0; i <= n; ++i) {
        vec2 uv = dp + ds.xy * sc;
        if (csm_outside(uv)) {  // crossed a side: search up to it, a miss unless under there
            float edge = csm_exit(dp, ds);
            if (!csm_under_at_exit(dp, ds, edge))
                return CsmHit(edge, i, CSM_MISS);
            sc = edge;
            return CsmHit(sc, i + 1, CSM_HIT);
        }
        if (1.0 - ds.z * sc <= textureLod(stepmap, uv, csm_lod).r)
            return CsmHit(sc, i + 1, CSM_HIT);
        prev_sc = sc;
        sc += dsc;
    }
    return CsmHit(sc, n + 1, CSM_CAP);  // horizontal ray: never reached the bottom
}

// steep parallax mapping refined as parallax occlusion mapping: the linear
// search, then the crossing of the ray with the segment between the two layers
CsmHit intersect_pom(vec2 dp, vec3 ds)
{
    float prev_sc;
    CsmHit hit = csm_linear_search(dp, ds, prev_sc);
    if (hit.status != CSM_HIT || hit.sc == 0.0)
        return hit;
    float a0 = 1.0 - ds.z * prev_sc - textureLod(stepmap, dp + ds.xy * prev_sc, csm_lod).r;  // > 0
    float a1 = 1.0 - ds.z * hit.sc - textureLod(stepmap, dp + ds.xy * hit.sc, csm_lod).r;     // <= 0
    hit.sc = mix(prev_sc, hit.sc, a0 / max(a0 - a1, 1e-30));
    return hit;
}

// relief mapping: the linear search, then binary_steps of binary search
CsmHit intersect_relief(vec2 dp, vec3 ds)
{
    float lo;
    CsmHit hit = csm_linear_search(dp, ds, lo);
    if (hit.status != CSM_HIT || hit.sc == 0.0)
        return hit;
    float hi = hit.sc;
    for (int i = 0; i < binary_steps; ++i) {
        float mid = 0.5 * (lo + hi);
        if (1.0 - ds.z * mid <= textureLod(stepmap, dp + ds.xy * mid, csm_lod).r)
            hi = mid;
        else
            lo = mid;
    }
    hit.sc = hi;
    hit.iterations += binary_steps;
    return hit;
}

#ifdef CSM_SELF_SHADOW
// Self-shadowing (the paper's future work): the light ray comes from above the relief
// down to the shaded point, so the same cones step it safely. Defined with
// CSM_SELF_SHADOW; csm_assets.shadow_reference answers the same question exactly.
//
// Hard: the shaded point is lit when the light ray's first hit is the point itself,
// i.e. the cone march (the _exact loop: cone step plus min_step texels, from where the
// ray enters the relief's top or a non-tiled side, towards the point) gets within the
// tolerance of the point without going under the surface: the last CSM_SHADOW_TOLERANCE
// texels of the ray (in texture space: uv and height alike), or the last
// CSM_SHADOW_HEIGHT_TOLERANCE of height it falls, whichever is longer (GPUs filter
// 8-bit maps to about 8 bits, so a steep light ray grazing its own point would
// otherwise meet the rounding). Soft (lightSize > 0, the light's angular radius in
// radians): at each sample, the angle seen from the point between the light ray and the
// surface point under (or over) the sample, in the light's vertical plane and in world units
// (world_scale); the smallest such angle m (negative once the ray is blocked) gives the share of
// the light's disc above a straight horizon m below its centre: 1/2 at m = 0, 0 at m <= -lightSize,
// 1 at m >= lightSize. A blocked ray goes on through the occluder (steps doubling from min_step)
// until m <= -lightSize or it reaches the point, so the penumbra reaches into the shadow too.
// Guards: a light at or below the horizon (ls.z <= 0) shadows (0); a light straight
// above lights a heightfield (the ray is the point's own vertical); a ray leaving
// a non-tiled side is unshadowed beyond it (nothing lies outside the map); the march
// stops after max_iterations steps (status CSM_CAP; the answer so far).

#ifndef CSM_SHADOW_TOLERANCE
#define CSM_SHADOW_TOLERANCE 1.0
#endif
#ifndef CSM_SHADOW_HEIGHT_TOLERANCE
#define CSM_SHADOW_HEIGHT_TOLERANCE (2.0 / 255.0)
#endif

uniform bool selfShadow;  // the material's switch (the define compiles the code in)
uniform float lightSize;  // angular radius of the light in radians; 0: hard shadows

struct CsmShadow {
    float lit;       // hard: 1 lit, 0 shadowed
    float soft;      // visible share of the light (== lit when lightSize is 0)
    int iterations;  // texture steps the march took
    int status;      // CSM_HIT reached the point or was blocked, CSM_CAP stopped by the cap
};

// Share of a disc of radius 1 above a straight edge at signed distance x from its centre.
float csm_disc_share(float x)
{
    x = clamp(x, -1.0, 1.0);
    return 1.0 - (acos(x) - x * sqrt(1.0 - x * x)) / 3.14159265358979;
}

// From the point at uv, height h (1 = top), towards the light: ls = the unit direction to the
// light in texture space (u, v, up: the view ray's space, turned up); world_scale = world length
// of one unit along u, v and height (for the soft angle).
CsmShadow csm_shadow(vec2 uv, float h, vec3 ls, vec3 world_scale)
{
    if (!(ls.z > 0.0))
        return CsmShadow(0.0, 0.0, 0, CSM_HIT);
    float tex = csm_texel();
    float target = max(1.0 - h, 0.0) / ls.z;           // from the top down to the point
    float edge = csm_exit(uv, vec3(ls.xy, 0.0));       // a non-tiled side, going towards the light
    float start = min(target, edge);
    vec3 ds = vec3(-ls.xy, ls.z);                      // down towards the point
    vec2 dp = uv + ls.xy * start;
    float z0 = h + ls.z * start;
    float stop = start - max(CSM_SHADOW_TOLERANCE * tex, CSM_SHADOW_HEIGHT_TOLERANCE / ls.z);
    float w = csm_min_step();
    float iz = sqrt(max(0.0, 1.0 - ds.z * ds.z));
    float margin = 1e30;
    float wl = length(ls * world_scale);
    float wr = length(ls.xy * world_scale.xy);
    int q = csm_map_quadrant(ds);
    float sc = 0.0;
    int i = 0;
    float lit = 1.0;
    float inside = w;                                  // steps through an occluder (soft only): doubling
    while (sc < stop) {
        if (i >= max_iterations)
            break;
        vec4 t = vec4(csm_fetch(dp + ds.xy * sc, q), 0.0, 0.0);
        float above = z0 - ds.z * sc - t.r;
        if (above <= 0.0) {
            lit = 0.0;
            if (!(lightSize > 0.0))
                return CsmShadow(0.0, 0.0, i + 1, CSM_HIT);
        }
        float dist = start - sc;                       // along the ray from the point
        if (wr > 1e-6 * wl) {                          // the light's vertical plane, world units
            float r = dist * wr;
            float vz = dist * ls.z * world_scale.z;
            margin = min(margin, atan(vz, r) - atan(vz - above * world_scale.z, r));
        }
        ++i;
        if (lit == 0.0 && !(margin > -lightSize))
            return CsmShadow(0.0, 0.0, i, CSM_HIT);
        if (above <= 0.0) {
            sc += inside;
            inside *= 2.0;
        } else {
            sc += w + csm_cone_step(above, t.g, ds, iz);
        }
    }
    float soft = lightSize > 0.0 ? csm_disc_share(margin / lightSize) : lit;
    return CsmShadow(lit, soft, i, i >= max_iterations ? CSM_CAP : CSM_HIT);
}
#endif
