// csm_shader.js: the shader side of csm_plugin.js: csmCompile(shader, material) is the
// material's onBeforeCompile. It resolves three's includes, adds the per-vertex frame and scale
// (VERT_*), the project's csm.glsl (csm_glsl.js) and the ray march at the start of main
// (FRAG_BEGIN), samples every map at the hit uv (their uv varyings get the hit's offset through
// their own transforms; textureGrad with the polygon's uv footprint), takes the normal from the
// step map's slopes when there is no normal map (a quadrant map's second image, stepmap2, with
// CSM_QUADRANT_MAPS), scales each direct light by
// its self-shadowed share (FRAG_SHADOW) and writes the debug views (FRAG_DEBUG).
// material.userData.csm.uniforms are the uniforms it adds.

import { ShaderChunk } from 'three';
import { CSM_GLSL } from './csm_glsl.js';
import { EXTENSION } from './csm_check.js';

function resolveIncludes(src) {
	return src.replace(/^[ \t]*#include +<([\w./]+)>/gm, (m, name) => {
		if (ShaderChunk[name] === undefined) throw new Error(`no shader chunk ${name}`);
		return resolveIncludes(ShaderChunk[name]);
	});
}

const VERT_HEAD = `
in vec4 csmTangent; in vec2 csmUv; in vec3 csmDpdu; in vec3 csmDpdv;
out vec3 csm_vNormal; out vec4 csm_vTangent; out vec2 csm_vUv; out vec3 csm_vScale; out vec3 csm_vView;
`;

const VERT_BODY = `
	csm_vView = mvPosition.xyz;
	csm_vNormal = normalize((modelViewMatrix * vec4(objectNormal, 0.0)).xyz);
	csm_vTangent = vec4(normalize((modelViewMatrix * vec4(csmTangent.xyz, 0.0)).xyz), csmTangent.w);
	csm_vUv = csmUv;
	vec3 csm_du = (modelViewMatrix * vec4(csmDpdu, 0.0)).xyz;
	vec3 csm_dv = (modelViewMatrix * vec4(csmDpdv, 0.0)).xyz;
	// uv units per view unit along u and v, and view length per uv unit (sqrt |dP/du x dP/dv|)
	csm_vScale = vec3(1.0 / max(length(csm_du), 1e-30), 1.0 / max(length(csm_dv), 1e-30),
	                  sqrt(length(cross(csm_du, csm_dv))));
`;

const FRAG_HEAD = `
in vec3 csm_vNormal; in vec4 csm_vTangent; in vec2 csm_vUv; in vec3 csm_vScale; in vec3 csm_vView;
uniform float csm_depth_scale;
uniform bool csm_enabled;
uniform bool csm_discard;
uniform int csm_debug;
uniform float csm_heat_max;
uniform mat2 csm_uv_inverse;
`;

// Self-shadowing (csm.glsl's csm_shadow, compiled in by CSM_SELF_SHADOW): each direct light's
// colour (point, spot, directional) is scaled by the visible share of it seen from the hit
// point, as shaders/surface_frag.glsl scales its diffuse term. The light direction is three's
// (for point and spot lights taken from the polygon, not the hit point).
const FRAG_SHADOW = `
bool csm_g_on = false;
vec2 csm_g_uv; float csm_g_h; vec3 csm_g_n, csm_g_tg, csm_g_bt, csm_g_scale; float csm_g_d;
vec4 csm_g_light = vec4(0.0), csm_g_shadow = vec4(0.0);
float csm_light_share(vec3 l) {
#ifdef CSM_SELF_SHADOW
	if (!csm_g_on || !selfShadow) return 1.0;
	vec3 ls = vec3(dot(l, csm_g_tg) * csm_g_scale.x, dot(l, csm_g_bt) * csm_g_scale.y, dot(l, csm_g_n) / csm_g_d);
	ls = length(ls) > 0.0 ? normalize(ls) : vec3(0.0, 0.0, 1.0);
	float top = textureLod(stepmap, csm_g_uv, csm_lod).r;
	CsmShadow sh = csm_shadow(csm_g_uv, max(csm_g_h, top), ls, vec3(1.0 / csm_g_scale.xy, csm_g_d));
	csm_g_light = vec4(ls, sh.lit);
	csm_g_shadow = vec4(sh.soft, float(sh.iterations), float(sh.status), 1.0);
	return sh.soft;
#else
	return 1.0;
#endif
}
`;

// Mirrors shaders/surface_frag.glsl (the ray in texture space), in view space.
const FRAG_BEGIN = `
	vec2 csm_delta = vec2(0.0);  // the hit's offset in CSM uvs; csm_raw_delta: in the mesh's uvs
	// the pixel's uv footprint before any branch: the march's level (csm.glsl's csm_march_lod, 0
	// without a level chain) and the gradients every shading fetch at the hit is filtered with
	vec2 csm_uv_dx = dFdx(csm_vUv), csm_uv_dy = dFdy(csm_vUv);
	vec2 csm_raw_dx = csm_uv_inverse * csm_uv_dx, csm_raw_dy = csm_uv_inverse * csm_uv_dy;
	csm_lod = csm_march_lod(csm_uv_dx, csm_uv_dy);
	vec2 csm_uv = csm_vUv;
	float csm_h = 1.0;
	CsmHit csm_hit = CsmHit(0.0, 0, CSM_HIT);
	vec3 csm_n = normalize(csm_vNormal);
	vec3 csm_tg = normalize(csm_vTangent.xyz - csm_n * dot(csm_n, csm_vTangent.xyz));
	vec3 csm_bt = -cross(csm_n, csm_tg) * (csm_vTangent.w < 0.0 ? -1.0 : 1.0);
	float csm_d = clamp(csm_depth_scale * csm_vScale.z, 1e-6, 1e6);
	vec3 csm_s = vec3(0.0, 0.0, 1.0);
	if (csm_enabled && gl_FrontFacing) {
		vec3 v = isOrthographic ? vec3(0.0, 0.0, -1.0) : normalize(csm_vView);
		csm_s = vec3(dot(v, csm_tg) * csm_vScale.x, dot(v, csm_bt) * csm_vScale.y, max(-dot(v, csm_n), 0.0) / csm_d);
		csm_s = length(csm_s) > 0.0 ? normalize(csm_s) : vec3(0.0, 0.0, 1.0);
		csm_hit = CSM_INTERSECT(csm_vUv, csm_s);
		if (csm_discard && csm_hit.status == CSM_MISS && csm_debug < 3) discard;
		csm_uv = csm_vUv + csm_s.xy * csm_hit.sc;
		csm_h = 1.0 - csm_s.z * csm_hit.sc;
		csm_delta = csm_uv - csm_vUv;
		csm_g_on = csm_hit.status != CSM_MISS;
		csm_g_uv = csm_uv; csm_g_h = csm_h; csm_g_n = csm_n; csm_g_tg = csm_tg; csm_g_bt = csm_bt;
		csm_g_scale = csm_vScale; csm_g_d = csm_d;
	}
	vec2 csm_raw_delta = csm_uv_inverse * csm_delta;
`;

// Without a normal map: the normal from the stored slopes (B = 0.5 + dh/dx, A = 0.5 - dh/dy).
const FRAG_NORMAL = `
#ifndef USE_NORMALMAP
	if (csm_enabled && gl_FrontFacing) {
#ifdef CSM_QUADRANT_MAPS
		vec4 csm_t = textureGrad(stepmap2, csm_uv, csm_uv_dx, csm_uv_dy);  // a quadrant map's second image holds the slopes
#else
		vec4 csm_t = textureGrad(stepmap, csm_uv, csm_uv_dx, csm_uv_dy);
#endif
		vec2 csm_texels = vec2(textureSize(stepmap, 0));
		float csm_gx = (csm_t.b - 0.5) * csm_texels.x * csm_vScale.x * csm_d;
		float csm_gy = (0.5 - csm_t.a) * csm_texels.y * csm_vScale.y * csm_d;
		normal = normalize(csm_n - csm_gx * csm_tg - csm_gy * csm_bt);
	}
#endif
`;

const FRAG_DEBUG = `
	if (csm_debug == 1) gl_FragColor = vec4(fract(csm_uv), csm_h, 1.0);
	else if (csm_debug == 2) {
		float x = clamp(float(csm_hit.iterations) / max(csm_heat_max, 1.0), 0.0, 1.0);
		gl_FragColor = vec4(clamp(vec3(1.5 - abs(4.0 * x - 3.0), 1.5 - abs(4.0 * x - 2.0), 1.5 - abs(4.0 * x - 1.0)), 0.0, 1.0), 1.0);
		if (csm_hit.status == CSM_CAP) gl_FragColor = vec4(1.0, 0.0, 1.0, 1.0);
	}
	else if (csm_debug == 3) gl_FragColor = vec4(csm_uv, csm_h, float(csm_hit.status + 1));
	else if (csm_debug == 4) gl_FragColor = vec4(float(csm_hit.iterations), float(csm_hit.status + 1), 0.0, 1.0);
	else if (csm_debug == 5) gl_FragColor = csm_g_light;
	else if (csm_debug == 6) gl_FragColor = csm_g_shadow;
`;

export function csmCompile(shader, material) {
	Object.assign(shader.uniforms, material.userData.csm.uniforms);
	let vs = resolveIncludes(shader.vertexShader);
	vs = vs.replace('void main() {', VERT_HEAD + 'void main() {');
	vs = vs.replace(/(\n[^\n]*gl_Position = projectionMatrix \* mvPosition;)/, '$1' + VERT_BODY);
	let fs = shader.fragmentShader.replace('#include <normal_fragment_maps>', '#include <normal_fragment_maps>\n//CSM_NORMAL');
	if (!fs.includes('//CSM_NORMAL')) throw new Error(`${EXTENSION}: no normal_fragment_maps in the material's shader`);
	fs = resolveIncludes(fs);
	const at = fs.indexOf('void main() {');
	let head = fs.slice(0, at), body = fs.slice(at + 'void main() {'.length);
	// every map is sampled at the hit: uv varyings inside texture lookups (vMapUv, made in the
	// vertex shader as mapTransform * uv) get the offset through their own transform,
	// with the lookup the polygon's uv footprint as its gradients (textureGrad: mipmaps filter at
	// distance, with no seams where the hit jumps at the relief's edges); lookups at a uv expression
	// (the bump map's neighbours) keep their own derivatives
	const transforms = new Set();
	const transform = (name) => {
		const t = name[0].toLowerCase() + name.slice(1) + 'Transform';
		transforms.add(t);
		return `mat2(${t})`;
	};
	body = body.replace(/\b(texture2D|texture)\(\s*(\w+)\s*,\s*v(\w+)Uv\s*\)/g, (m, fn, map, name) => {
		const t = transform(name);
		return `textureGrad( ${map}, v${name}Uv + ${t} * csm_raw_delta, ${t} * csm_raw_dx, ${t} * csm_raw_dy )`;
	});
	body = body.replace(/\b(texture2D|texture)\(\s*(\w+)\s*,\s*v(\w+)Uv\b/g,
		(m, fn, map, name) => `${fn}( ${map}, (v${name}Uv + ${transform(name)} * csm_raw_delta)`);
	for (const t of transforms) if (!new RegExp(`uniform\\s+mat3\\s+${t}\\b`).test(head)) head += `uniform mat3 ${t};\n`;
	head += FRAG_HEAD + CSM_GLSL + '\n' + FRAG_SHADOW;
	// each direct light's colour times its visible share (1 without self-shadowing)
	body = body.replace(/\bRE_Direct\(\s*directLight\s*,/g, 'directLight.color *= csm_light_share(directLight.direction); $&');
	const close = body.lastIndexOf('}');
	body = FRAG_BEGIN + body.slice(0, close).replace('//CSM_NORMAL', FRAG_NORMAL) + FRAG_DEBUG + '}\n' + body.slice(close + 1);
	shader.vertexShader = vs;
	shader.fragmentShader = head + 'void main() {' + body;
}
