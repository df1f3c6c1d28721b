// surface_frag.glsl: a cone step mapped surface (GLSL 330 core), after csm.glsl.
//
// Define CSM_INTERSECT to the intersection function to use (intersect_cone_exact,
// intersect_cone_loop, intersect_cone_fixed, intersect_parallax, intersect_pom,
// intersect_relief). Define CSM_DISCARD_MISSES to discard pixels whose ray left
// a non-tiled texture (the debug targets keep them otherwise).
//
// Texture space: u along the tangent, v (growing down the image, glTF) against the
// glTF bitangent cross(normal, tangent) * w, and the relief hangs
// under the polygon: height 1 is the polygon, height 0 lies `depth` world units
// below it. uv_per_world converts world lengths along the tangent and bitangent
// to texture units: (u, v) = uv_per_world * (along tg, along bt), the inverse of the
// surface derivatives dP/du, dP/dv written in that frame (a diagonal, 1 / the world
// size the texture spans, where they are at right angles; a rotated, non-uniformly
// scaled KHR_texture_transform shears them).
//
// Outputs: 0 colour (ambient + diffuse, as in the paper's main; far away blended with its pixel
//          quad's neighbours: csm.glsl's csm_quad_share);
//          1 (hit u, hit v, hit height, ray parameter sc), uv not wrapped;
//          2 (iterations, status, depth along the view axis of the hit, 1);
// with CSM_RAY_OUTPUTS defined (verify), also the ray the intersection started from:
//          3 (start u, start v, the marched level csm_lod, 1); 4 (direction u, v, down, 1).
// Define CSM_SELF_SHADOW for self-shadowing (csm.glsl's csm_shadow), switched by the
// uniform selfShadow: the diffuse term is multiplied by the visible share of the light,
// the shadow steps are added to the iterations of output 2, and with CSM_RAY_OUTPUTS
//          5 (light direction u, v, up, hard lit); 6 (soft, shadow steps, shadow status, 1).
// light_direction: a directional light (world, towards the light) when not zero, else
// the point light `light`. The shaded point is the ray's hit lifted onto the surface
// where the ray ended under it (pom, relief, the back-off of exact leave it above).

#ifndef CSM_INTERSECT
#define CSM_INTERSECT intersect_cone_exact
#endif

in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;

uniform vec3 eye;           // camera position, world
uniform mat4 view;          // world to camera (for the view-axis depth)
uniform vec3 light;         // point light position, world
uniform vec4 ambient;
uniform vec4 diffuse;
uniform float depth;        // world depth of the full height range; clamped to [1e-6, 1e6]
uniform mat2 uv_per_world;
uniform bool use_texmap;
uniform sampler2D texmap;   // colour texture, sampled at the hit

layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_hit;
layout(location = 2) out vec4 frag_info;
#ifdef CSM_RAY_OUTPUTS
layout(location = 3) out vec4 frag_ray_uv;
layout(location = 4) out vec4 frag_ray_dir;
#ifdef CSM_SELF_SHADOW
layout(location = 5) out vec4 frag_light;
layout(location = 6) out vec4 frag_shadow;
#endif
#endif
uniform vec3 light_direction;  // world, towards a directional light; zero: the point light

void main()
{
    vec3 n = normalize(v_normal);
    vec3 tg = normalize(v_tangent.xyz - n * dot(n, v_tangent.xyz));
    // glTF: the bitangent cross(n, tg) * w points up the image, towards decreasing v
    vec3 bt = -cross(n, tg) * (v_tangent.w < 0.0 ? -1.0 : 1.0);
    float d = clamp(depth, 1e-6, 1e6);

    // the view ray in texture space (u, v, down), then normalized as the paper needs
    vec3 v = normalize(v_world - eye);
    vec3 s = vec3(uv_per_world * vec2(dot(v, tg), dot(v, bt)), max(-dot(v, n), 0.0) / d);
    s = length(s) > 0.0 ? normalize(s) : vec3(0.0, 0.0, 1.0);

    // the pixel's uv footprint, taken before the march's loops (uniform control flow): the
    // march's level (csm_march_lod: level 0 without a chain) and, at the hit, the shading fetches'
    // gradients (csm_shading_grads)
    vec2 uv_dx = dFdx(v_uv);
    vec2 uv_dy = dFdy(v_uv);
    csm_lod = csm_march_lod(uv_dx, uv_dy);
    float share = csm_quad_weight(uv_dx, uv_dy);
    float spread = csm_tap_spread(uv_dx, uv_dy);
    CsmHit hit = CSM_INTERSECT(v_uv, s);
#ifdef CSM_RAY_OUTPUTS
    frag_ray_uv = vec4(v_uv, csm_lod, 1.0);
    frag_ray_dir = vec4(s, 1.0);
#endif
#ifdef CSM_DISCARD_MISSES
    if (hit.status == CSM_MISS)
        discard;
#endif
    vec2 uv = v_uv + s.xy * hit.sc;
    float h = 1.0 - s.z * hit.sc;

    // normal from the stored slopes: B = 0.5 + dh/dx, A = 0.5 - dh/dy per texel, filtered over the
    // pixel's visible footprint (csm_shading_grads: a sampler with mipmaps averages them at distance),
    // far away at four taps weighted by what the pixel sees of each (csm_visible_taps)
    csm_shading_grads(uv, s, uv_dx, uv_dy);
    CsmTaps taps = csm_visible_taps(uv, s, uv_dx, uv_dy, spread);
    vec2 texels = vec2(textureSize(stepmap, 0));
    // world rise per world step along tg and bt: the slopes per uv unit through uv_per_world
    vec2 g = transpose(uv_per_world) * (taps.slope * texels) * d;
    vec3 normal = normalize(n - g.x * tg - g.y * bt);

    mat2 world_per_uv = inverse(uv_per_world);  // columns: dP/du, dP/dv along (tg, bt)
    vec2 moved = world_per_uv * (s.xy * hit.sc);
    vec3 p = v_world + tg * moved.x + bt * moved.y - n * (d * s.z * hit.sc);
    vec3 l = dot(light_direction, light_direction) > 0.0 ? normalize(light_direction) : normalize(light - p);
    vec3 c = use_texmap ? csm_tapped(texmap, taps, uv, mat2(1.0)).rgb : vec3(1.0);
    float lit = max(0.0, dot(normal, l));
    int iterations = hit.iterations;
#ifdef CSM_SELF_SHADOW
    vec3 ls = vec3(uv_per_world * vec2(dot(l, tg), dot(l, bt)), dot(l, n) / d);
    ls = length(ls) > 0.0 ? normalize(ls) : vec3(0.0, 0.0, 1.0);
    CsmShadow sh = CsmShadow(1.0, 1.0, 0, CSM_HIT);
    if (selfShadow)
        sh = csm_shadow(uv, max(h, textureLod(stepmap, uv, csm_lod).r), ls,
                        vec3(length(world_per_uv[0]), length(world_per_uv[1]), d));
    lit *= sh.soft;
    iterations += sh.iterations;
#ifdef CSM_RAY_OUTPUTS
    frag_light = vec4(ls, sh.lit);
    frag_shadow = vec4(sh.soft, float(sh.iterations), float(sh.status), 1.0);
#endif
#endif
    frag_color = vec4(csm_quad_share(ambient.rgb * c + c * diffuse.rgb * lit, share),
                      hit.status == CSM_MISS ? 0.0 : 1.0);
    frag_hit = vec4(uv, h, hit.sc);
    frag_info = vec4(float(iterations), float(hit.status), -(view * vec4(p, 1.0)).z, 1.0);
}
