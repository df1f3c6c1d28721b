// csm_babylon_shader.js: the shader side of csm_babylon.js: the code a Babylon.js
// MaterialPluginBase splices into PBRMaterial's GLSL (getCustomCode): the per-vertex frame and
// scale in world space, the project's csm.glsl (csm_glsl.js) with the glue both plugins share
// (csm_frag.js), the march at the start of main, every map's sample moved to the hit uv through
// its own texture matrix and filtered there as three.js' plugin filters it (each
// `TEXRD(xSampler,vXUV+uvOffset)` of Babylon's a csm_tapped: textureGrad over the pixel's visible
// footprint, far away four taps weighted by what the pixel sees), the normal from the step map's
// slopes without a normal map, each point, spot and
// directional light times its self-shadowed share, and the debug views after the final colour.
// Everything sits under the define CSM, which the plugin sets per mesh. GLSL ES 3.00 (WebGL2):
// Babylon converts its own attribute/varying before it splices this in.

import { CSM_GLSL } from './csm_glsl.js';
import { CSM_FRAG_GLSL, CSM_VERT_GLSL } from './csm_frag.js';

// Babylon's own preprocessor evaluates #if before the GLSL compiler sees it, and it cannot do
// arithmetic: the unrolled fixed variant's `#if (CSM_FIXED_STEPS / n) % 2 == 1` become
// `#ifdef CSM_FIXED_BITn`, defines the plugin sets from the step count (fixedBits).
const BIT_LINE = /^#if \(CSM_FIXED_STEPS \/ (\d+)\) % 2 == 1$/gm;
const BIT_ONE = '#if CSM_FIXED_STEPS % 2 == 1';
export const FIXED_BITS = [1, 2, 4, 8, 16, 32, 64];

// Its comments go too (Babylon takes a shader holding the text "#version 3", as csm.glsl's header
// does, for one converted to GLSL ES 3.00 already), and its line continuations (Babylon's
// preprocessor reads a shader line by line): the fixed variant's step macro becomes one line.
function babylonGlsl(src) {
	const out = src.replace(/[ \t]*\/\/[^\n]*/g, '').replace(/\\\n/g, ' ').replace(BIT_LINE, '#ifdef CSM_FIXED_BIT$1').replace(BIT_ONE, '#ifdef CSM_FIXED_BIT1');
	const left = out.match(/^#if\b(?!def|ndef).*$/gm);
	if (left) throw new Error(`csm_babylon_shader.js: csm.glsl holds an #if Babylon cannot evaluate: ${left[0]}`);
	return out;
}

// The defines CSM_FIXED_BIT<n> of a step count (1..127): { CSM_FIXED_BIT1: bool, ... }.
export function fixedBits(steps) {
	return Object.fromEntries(FIXED_BITS.map((b) => [`CSM_FIXED_BIT${b}`, (Math.floor(steps / b) % 2) === 1]));
}

// The names of the maps whose uv Babylon's PBR shader moves by uvOffset and whose texture matrix
// (x -> xMatrix) is in its uniform block: their offset goes through that matrix's linear part.
const MAPS = ['Albedo', 'BaseWeight', 'BaseDiffuseRoughness', 'Ambient', 'BentNormal', 'Opacity', 'Emissive',
	'Lightmap', 'Reflectivity', 'MicroSurfaceSampler', 'Bump', 'MetallicReflectance', 'Reflectance'];

const VERTEX_DEFINITIONS = `
#ifdef CSM
in vec4 csmTangent; in vec2 csmUv; in vec3 csmDpdu; in vec3 csmDpdv;
out vec3 csm_vNormal; out vec4 csm_vTangent; out vec2 csm_vUv; out mat2 csm_vFrame; out float csm_vSize;
${CSM_VERT_GLSL}
#endif
`;

// World space (the frame of vPositionW and vEyePosition); a mirroring world matrix (Babylon's
// glTF root in a left-handed scene) flips the bitangent's handedness.
const VERTEX_MAIN_END = `
#ifdef CSM
	mat3 csm_world = mat3(finalWorld);
	csm_vNormal = normalize(csm_world * normalUpdated);
	csm_vTangent = vec4(normalize(csm_world * csmTangent.xyz), csmTangent.w * (determinant(csm_world) < 0.0 ? -1.0 : 1.0));
	csm_vUv = csmUv;
	vec3 csm_du = csm_world * csmDpdu, csm_dv = csm_world * csmDpdv;
	// uv units per world unit along the tangent and bitangent, and world length per uv unit (sqrt |dP/du x dP/dv|)
	csm_vFrame = csm_uv_frame(csm_vNormal, csm_vTangent, csm_du, csm_dv);
	csm_vSize = sqrt(length(cross(csm_du, csm_dv)));
#endif
`;

const FRAGMENT_DEFINITIONS = (glsl) => `
#ifdef CSM
in vec3 csm_vNormal; in vec4 csm_vTangent; in vec2 csm_vUv; in mat2 csm_vFrame; in float csm_vSize;
${glsl}
${CSM_FRAG_GLSL}
vec4 csm_sample(sampler2D map, vec2 uv, vec2 dx, vec2 dy, mat2 matrix) {
	return csm_tapped(map, csm_f.taps, uv, matrix * csm_uv_inverse);
}
#else
float csm_light_share(vec3 l) { return 1.0; }
vec4 csm_sample(sampler2D map, vec2 uv, vec2 dx, vec2 dy, mat2 matrix) { return textureGrad(map, uv, dx, dy); }
#endif
`;

// The march (it sets csm.glsl's csm_lod from the pixel's uv footprint) and the hit's offset.
const FRAGMENT_MAIN_BEGIN = `
	vec2 csm_raw_delta = vec2(0.0);  // the hit's offset in the mesh's uvs
#ifdef CSM
	csm_f = csm_frag_march(csm_enabled && gl_FrontFacing, normalize(vPositionW - vEyePosition.xyz),
	                       csm_vNormal, csm_vTangent, csm_vUv, csm_vFrame, csm_vSize, csm_depth_scale);
	if (csm_discard && csm_f.hit.status == CSM_MISS && csm_debug < 3) discard;
	csm_raw_delta = csm_uv_inverse * (csm_f.uv - csm_vUv);
#endif
`;

// Without a normal map (BUMP): the normal from the stored slopes, before the albedo block.
const NORMAL = `
#if defined(CSM) && !defined(BUMP)
	if (csm_enabled && gl_FrontFacing) normalW = csm_frag_normal(csm_f);
#endif
albedoOpacityOutParams albedoOpacityOut;`;

const FRAGMENT_MAIN_END = `
#ifdef CSM
	gl_FragColor = csm_frag_debug(csm_debug, csm_f, csm_g_light, csm_g_shadow, csm_heat_max, gl_FragColor, albedoOpacityOut.surfaceAlbedo);
#endif
`;

let fragmentGlsl = null;  // csm.glsl as Babylon's preprocessor can read it, made once

// getCustomCode's answer for shaderType 'vertex' or 'fragment' (keys starting with ! are regular
// expressions, applied to the shader with its includes resolved).
export function customCode(shaderType) {
	if (shaderType === 'vertex') return { CUSTOM_VERTEX_DEFINITIONS: VERTEX_DEFINITIONS, CUSTOM_VERTEX_MAIN_END: VERTEX_MAIN_END };
	if (shaderType !== 'fragment') return null;
	fragmentGlsl ??= babylonGlsl(CSM_GLSL);
	const code = {
		CUSTOM_FRAGMENT_DEFINITIONS: FRAGMENT_DEFINITIONS(fragmentGlsl),
		CUSTOM_FRAGMENT_MAIN_BEGIN: FRAGMENT_MAIN_BEGIN,
		CUSTOM_FRAGMENT_MAIN_END: FRAGMENT_MAIN_END,
		'!albedoOpacityOutParams albedoOpacityOut;': NORMAL,
		// point, spot and directional lights (not hemispheric or area ones): times the visible share
		'!preInfo\\.roughness=adjustRoughnessFromLightProperties\\(':
			'preInfo.attenuation*=csm_light_share(preInfo.L);preInfo.roughness=adjustRoughnessFromLightProperties(',
	};
	// each map's sample (TEXRD: Babylon's texture2D; its texture-repetition sampling is not kept)
	// at the hit, filtered as csm_frag.js' taps say (csm.glsl's csm_tapped: over the pixel's visible
	// footprint, no seams where the hit jumps; far away four taps weighted by what the pixel sees),
	// the taps' offsets and gradients through the map's matrix; without CSM its own footprint
	// (the closing parenthesis stays: Babylon ends each injection with a line break)
	const sample = (uv) => `!\\b(TEXRD|texture2D|texture)\\((\\w+),(${uv})\\+uvOffset(?=\\))`;
	const grad = (matrix) => `csm_sample($2,$3+uvOffset+${matrix}*csm_raw_delta,dFdx($3),dFdy($3),${matrix}`;
	for (const map of MAPS) code[sample(`v${map}UV`)] = grad(`mat2(${map[0].toLowerCase() + map.slice(1)}Matrix)`);
	// any other map (clear coat, sheen, ...): the offset as if its uvs were the step map's
	code[sample(`v(?!(?:${MAPS.join('|')})UV)\\w+UV`)] = grad('mat2(1.0)');
	return code;
}
