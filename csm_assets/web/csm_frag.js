// csm_frag.js: the fragment glue around csm.glsl that both plugins splice into their engine's
// PBR shader (three.js: csm_shader.js, Babylon.js: csm_babylon_shader.js), with no engine
// names: the view ray into texture space and its march (csm_frag_march, as
// shaders/surface_frag.glsl does it, in whatever space the engine gives the frame and view
// ray in), the normal from the step map's slopes (csm_frag_normal), a direct light's
// self-shadowed share (csm_light_share of the global csm_f, with CSM_SELF_SHADOW) and the debug
// views (csm_frag_debug, csm_settings.js' DEBUG). Goes after CSM_GLSL (csm_glsl.js). CSM_VERT_GLSL
// goes into the vertex shader.

// csm_uv_frame(n, tangent, du, dv): uv units per unit along the frame's tangent and bitangent
// (towards +v) of a unit normal n and a glTF tangent (xyz, w: handedness) from the surface
// derivatives du, dv (position per CSM uv unit: csm_frame.js' dpdu, dpdv), all in one space: the
// inverse of du, dv written in that frame. The texture's axes need not be at right angles there
// (a rotated, non-uniformly scaled KHR_texture_transform shears them); at right angles it is
// diag(1 / |du|, 1 / |dv|), which it also falls back to where du, dv have no area.
export const CSM_VERT_GLSL = `
mat2 csm_uv_frame(vec3 n, vec4 tangent, vec3 du, vec3 dv) {
	vec3 tg = normalize(tangent.xyz - n * dot(n, tangent.xyz));
	vec3 bt = -cross(n, tg) * (tangent.w < 0.0 ? -1.0 : 1.0);
	mat2 j = mat2(dot(du, tg), dot(du, bt), dot(dv, tg), dot(dv, bt));
	if (abs(determinant(j)) > 1e-30) return inverse(j);
	return mat2(1.0 / max(length(du), 1e-30), 0.0, 0.0, 1.0 / max(length(dv), 1e-30));
}
`;

export const CSM_FRAG_GLSL = `
uniform float csm_depth_scale;  // depthScale
uniform bool csm_enabled;       // false: the plain material's uv (the relief off)
uniform bool csm_discard;       // discard rays that leave a non-tiled map (not in the raw views)
uniform int csm_debug;          // the debug view (csm_settings.js' DEBUG)
uniform float csm_heat_max;     // iterations shown red in the heat map
uniform mat2 csm_uv_inverse;    // CSM uv offsets back to the mesh's uvs

struct CsmFrag {
	vec2 uv;         // the hit's CSM uv (the polygon's where nothing is marched)
	float h;         // the hit's height (1: the top)
	CsmHit hit;      // csm.glsl's answer (CSM_HIT, 0 iterations where nothing is marched)
	vec3 n, tg, bt;  // unit normal, tangent (+u) and bitangent (up the image, towards -v)
	vec3 s;          // the view ray in texture space (u, v, down)
	mat2 m;          // uv units per unit along tg and bt (csm_uv_frame)
	vec2 dx, dy;     // the shading fetches' gradients: the polygon's CSM uv change per pixel across and
	                 // down the screen (its footprint), at a hit csm.glsl's csm_shading_grads
	CsmTaps taps;    // where the shading fetches read (csm_tapped): far away at a hit four taps weighted by
	                 // what the pixel sees of each (csm.glsl's csm_visible_taps), else one at uv
	float d;         // depth of a unit of height (depthScale times the length per uv unit)
	bool on;         // marched and not missed: the hit is on the surface
	float share;     // the weight of the pixel quad's neighbours in the lit colour (csm_quad_weight)
};

// The view ray's march: march false leaves the polygon's uv. view: the unit direction from the eye
// to the point; normal, tangent (w: handedness; the bitangent is cross(n, t) * w, negated: glTF's
// v grows downward) and view in one space; frame: uv units per unit along the tangent and
// bitangent (csm_uv_frame), size: length per uv unit (the square root of |du x dv|), in that
// space; uv: the CSM uv (the step map's, placed).
// Call it in uniform control flow (it takes uv's derivatives): it sets the march's level, csm_lod
// (csm.glsl's csm_march_lod, 0 without a level chain), from the footprint; every shading fetch at
// the hit is filtered over the pixel's visible footprint (the shorter axis, csm_shading_grads),
// far away at four taps weighted by what the pixel sees (csm_tapped(map, f.taps, ...)).
CsmFrag csm_frag_march(bool march, vec3 view, vec3 normal, vec4 tangent, vec2 uv, mat2 frame, float size,
                       float depth_scale) {
	CsmFrag f;
	f.uv = uv; f.h = 1.0; f.hit = CsmHit(0.0, 0, CSM_HIT); f.on = false; f.m = frame;
	f.dx = dFdx(uv); f.dy = dFdy(uv);
	csm_lod = csm_march_lod(f.dx, f.dy);
	f.share = march ? csm_quad_weight(f.dx, f.dy) : 0.0;
	float spread = march ? csm_tap_spread(f.dx, f.dy) : 0.0;
	f.n = normalize(normal);
	f.tg = normalize(tangent.xyz - f.n * dot(f.n, tangent.xyz));
	f.bt = -cross(f.n, f.tg) * (tangent.w < 0.0 ? -1.0 : 1.0);
	f.d = clamp(depth_scale * size, 1e-6, 1e6);
	f.s = vec3(0.0, 0.0, 1.0);
	if (march) {
		f.s = vec3(f.m * vec2(dot(view, f.tg), dot(view, f.bt)), max(-dot(view, f.n), 0.0) / f.d);
		f.s = length(f.s) > 0.0 ? normalize(f.s) : vec3(0.0, 0.0, 1.0);
		f.hit = CSM_INTERSECT(uv, f.s);
		f.uv = uv + f.s.xy * f.hit.sc;
		f.h = 1.0 - f.s.z * f.hit.sc;
		f.on = f.hit.status != CSM_MISS;
		csm_shading_grads(f.uv, f.s, f.dx, f.dy);
	}
	f.taps = csm_visible_taps(f.uv, f.s, f.dx, f.dy, spread);
	return f;
}

// The normal at the hit from the stored slopes (B = 0.5 + dh/dx, A = 0.5 - dh/dy; a quadrant
// map's in its second image, stepmap2, with CSM_QUADRANT_MAPS), in the frame's space; filtered
// over the pixel's visible footprint (mipmaps, where the engine made them, filter far away), finer
// than the colour and far away weighted by what the pixel sees (csm.glsl's csm_visible_taps).
vec3 csm_frag_normal(CsmFrag f) {
	vec2 texels = vec2(textureSize(stepmap, 0));
	vec2 g = transpose(f.m) * (f.taps.slope * texels) * f.d;  // rise along tg, bt
	return normalize(f.n - g.x * f.tg - g.y * f.bt);
}

#ifdef CSM_SELF_SHADOW
// The visible share of a direct light towards unit direction l (the frame's space) from the hit
// (csm.glsl's csm_shadow); light = (l in texture space, hard lit) and shadow = (soft share,
// shadow steps, status, 1) for the debug views.
float csm_frag_shadow(CsmFrag f, vec3 l, out vec4 light, out vec4 shadow) {
	vec3 ls = vec3(f.m * vec2(dot(l, f.tg), dot(l, f.bt)), dot(l, f.n) / f.d);
	ls = length(ls) > 0.0 ? normalize(ls) : vec3(0.0, 0.0, 1.0);
	float top = textureLod(stepmap, f.uv, csm_lod).r;
	mat2 per_uv = inverse(f.m);  // columns: du, dv along tg, bt
	CsmShadow sh = csm_shadow(f.uv, max(f.h, top), ls, vec3(length(per_uv[0]), length(per_uv[1]), f.d));
	light = vec4(ls, sh.lit);
	shadow = vec4(sh.soft, float(sh.iterations), float(sh.status), 1.0);
	return sh.soft;
}
#endif

// The fragment's march and the last shaded light's debug values, for csm_light_share.
CsmFrag csm_f;
vec4 csm_g_light = vec4(0.0), csm_g_shadow = vec4(0.0);

// The share of a direct light towards unit direction l that reaches the hit (1 without
// CSM_SELF_SHADOW, off the surface, or with the selfShadow uniform false). The engine's glue
// multiplies each direct light by it.
float csm_light_share(vec3 l) {
#ifdef CSM_SELF_SHADOW
	if (!csm_f.on || !selfShadow) return 1.0;
	return csm_frag_shadow(csm_f, l, csm_g_light, csm_g_shadow);
#else
	return 1.0;
#endif
}

// Debug view mode (csm_settings.js' DEBUG) of the fragment; lit for 0 (and unknown modes), far
// away blended with its pixel quad's neighbours (csm_quad_share; mode is uniform, so this is
// uniform control flow).
vec4 csm_frag_debug(int mode, CsmFrag f, vec4 light, vec4 shadow, float heat_max, vec4 lit, vec3 albedo) {
	if (mode == 1) return vec4(fract(f.uv), f.h, 1.0);
	if (mode == 2) {
		if (f.hit.status == CSM_CAP) return vec4(1.0, 0.0, 1.0, 1.0);
		float x = clamp(float(f.hit.iterations) / max(heat_max, 1.0), 0.0, 1.0);
		return vec4(clamp(vec3(1.5 - abs(4.0 * x - 3.0), 1.5 - abs(4.0 * x - 2.0), 1.5 - abs(4.0 * x - 1.0)), 0.0, 1.0), 1.0);
	}
	if (mode == 3) return vec4(f.uv, f.h, float(f.hit.status + 1));
	if (mode == 4) return vec4(float(f.hit.iterations), float(f.hit.status + 1), 0.0, 1.0);
	if (mode == 5) return light;
	if (mode == 6) return shadow;
	if (mode == 7) return vec4(csm_quad_share(albedo, f.share), 1.0);
	return vec4(csm_quad_share(lit.rgb, f.share), lit.a);
}
`;
