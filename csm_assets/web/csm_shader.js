// csm_shader.js: the shader side of csm_plugin.js: csmCompile(shader, material) is the
// material's onBeforeCompile. It resolves three's includes, adds the per-vertex frame and scale
// (VERT_*), the project's csm.glsl (csm_glsl.js) with the glue both plugins share (csm_frag.js)
// and the ray march at the start of main (FRAG_BEGIN), samples every map at the hit uv (their uv
// varyings get the hit's offset through their own transforms; csm_tapped over the pixel's visible
// footprint), takes the normal from the step map's slopes when there is no normal map
// (FRAG_NORMAL), scales each direct light by its self-shadowed share (csm_light_share) and writes
// the debug views (FRAG_DEBUG).
// material.userData.csm.uniforms are the uniforms it adds.

import { ShaderChunk } from 'three';
import { CSM_GLSL } from './csm_glsl.js';
import { CSM_FRAG_GLSL, CSM_VERT_GLSL } from './csm_frag.js';
import { EXTENSION } from './csm_check.js';

function resolveIncludes(src) {
	return src.replace(/^[ \t]*#include +<([\w./]+)>/gm, (m, name) => {
		if (ShaderChunk[name] === undefined) throw new Error(`no shader chunk ${name}`);
		return resolveIncludes(ShaderChunk[name]);
	});
}

const VERT_HEAD = `
in vec4 csmTangent; in vec2 csmUv; in vec3 csmDpdu; in vec3 csmDpdv;
out vec3 csm_vNormal; out vec4 csm_vTangent; out vec2 csm_vUv; out vec3 csm_vView;
out mat2 csm_vFrame; out float csm_vSize;
${CSM_VERT_GLSL}`;

const VERT_BODY = `
	csm_vView = mvPosition.xyz;
	csm_vNormal = normalize((modelViewMatrix * vec4(objectNormal, 0.0)).xyz);
	csm_vTangent = vec4(normalize((modelViewMatrix * vec4(csmTangent.xyz, 0.0)).xyz), csmTangent.w);
	csm_vUv = csmUv;
	vec3 csm_du = (modelViewMatrix * vec4(csmDpdu, 0.0)).xyz;
	vec3 csm_dv = (modelViewMatrix * vec4(csmDpdv, 0.0)).xyz;
	// uv units per view unit along the tangent and bitangent, and view length per uv unit (sqrt |dP/du x dP/dv|)
	csm_vFrame = csm_uv_frame(csm_vNormal, csm_vTangent, csm_du, csm_dv);
	csm_vSize = sqrt(length(cross(csm_du, csm_dv)));
`;

const FRAG_HEAD = `
in vec3 csm_vNormal; in vec4 csm_vTangent; in vec2 csm_vUv; in vec3 csm_vView;
in mat2 csm_vFrame; in float csm_vSize;
`;

// The march (csm_frag.js) at the start of main, in view space: it sets csm.glsl's csm_lod from the
// pixel's uv footprint; the hit's offset in the mesh's uvs (csm_raw_delta) moves every map's
// lookup to the hit, and csm_f.taps filter it there.
const FRAG_BEGIN = `
	csm_f = csm_frag_march(csm_enabled && gl_FrontFacing, isOrthographic ? vec3(0.0, 0.0, -1.0) : normalize(csm_vView),
	                       csm_vNormal, csm_vTangent, csm_vUv, csm_vFrame, csm_vSize, csm_depth_scale);
	if (csm_discard && csm_f.hit.status == CSM_MISS && csm_debug < 3) discard;
	vec2 csm_raw_delta = csm_uv_inverse * (csm_f.uv - csm_vUv);
`;

// Without a normal map: the normal from the stored slopes.
const FRAG_NORMAL = `
#ifndef USE_NORMALMAP
	if (csm_enabled && gl_FrontFacing) normal = csm_frag_normal(csm_f);
#endif
`;

const FRAG_DEBUG = `
	gl_FragColor = csm_frag_debug(csm_debug, csm_f, csm_g_light, csm_g_shadow, csm_heat_max, gl_FragColor, diffuseColor.rgb);
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
	// vertex shader as mapTransform * uv) get the offset through their own transform, and the
	// lookup becomes csm_tapped's (csm_frag.js' taps: textureGrad over the pixel's visible
	// footprint, so mipmaps filter at distance with no seams where the hit jumps at the relief's
	// edges; far away four taps weighted by what the pixel sees), its offsets and gradients through
	// the same transform; lookups at a uv expression (the bump map's neighbours) keep their own
	// derivatives
	const transforms = new Set();
	const transform = (name) => {
		const t = name[0].toLowerCase() + name.slice(1) + 'Transform';
		transforms.add(t);
		return `mat2(${t})`;
	};
	body = body.replace(/\b(texture2D|texture)\(\s*(\w+)\s*,\s*v(\w+)Uv\s*\)/g, (m, fn, map, name) => {
		const t = transform(name);
		return `csm_tapped( ${map}, csm_f.taps, v${name}Uv + ${t} * csm_raw_delta, ${t} * csm_uv_inverse )`;
	});
	body = body.replace(/\b(texture2D|texture)\(\s*(\w+)\s*,\s*v(\w+)Uv\b/g,
		(m, fn, map, name) => `${fn}( ${map}, (v${name}Uv + ${transform(name)} * csm_raw_delta)`);
	for (const t of transforms) if (!new RegExp(`uniform\\s+mat3\\s+${t}\\b`).test(head)) head += `uniform mat3 ${t};\n`;
	head += FRAG_HEAD + CSM_GLSL + '\n' + CSM_FRAG_GLSL;
	// Self-shadowing (csm_frag.js' csm_light_share, compiled in by CSM_SELF_SHADOW): each direct
	// light's colour (point, spot, directional) times its visible share seen from the hit point, as
	// shaders/surface_frag.glsl scales its diffuse term; the light direction is three's (for point
	// and spot lights taken from the polygon, not the hit point)
	body = body.replace(/\bRE_Direct\(\s*directLight\s*,/g, 'directLight.color *= csm_light_share(directLight.direction); $&');
	const close = body.lastIndexOf('}');
	body = FRAG_BEGIN + body.slice(0, close).replace('//CSM_NORMAL', FRAG_NORMAL) + FRAG_DEBUG + '}\n' + body.slice(close + 1);
	shader.vertexShader = vs;
	shader.fragmentShader = head + 'void main() {' + body;
}
