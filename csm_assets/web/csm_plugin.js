// csm_plugin.js: a three.js GLTFLoader plugin for EXT_materials_cone_step_mapping (csm-assets).
//
//   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
//   import { CSMExtension } from './csm_plugin.js';
//   const loader = new GLTFLoader();
//   loader.register((parser) => new CSMExtension(parser));
//   loader.load('scene.gltf', (gltf) => scene.add(gltf.scene));
//
// Needs three >= 0.160 (WebGL2, GLSL ES 3.00; tested with 0.180.0) and a WebGLRenderer.
// Each material carrying the extension keeps its MeshStandardMaterial PBR shading; an
// onBeforeCompile hook traces the view ray through the step map (the project's csm.glsl,
// the material's own variant and steps) and samples every map at the hit uv. Directions
// come from the glTF TANGENT (the bitangent cross(n, t) * w points up the image, towards
// -v); the texture-space scale from the mesh's world size per uv unit, per vertex and per
// axis (csm-assets' verify draws with one isotropic scale per primitive, sqrt(uv area /
// world area): the same where the uvs are not stretched more along u than along v).
// The step map's textureInfo places it as convert wrote it: its texCoord and
// KHR_texture_transform (offset, rotation, scale, and the extension's texCoord override)
// map the mesh's uvs to the CSM uvs, on which the tangent frame and texel scale are taken
// (as csm-assets' own renderer does); its sampler's wrap modes become REPEAT on tiled axes
// and CLAMP_TO_EDGE elsewhere (the extension's `tile`), LINEAR without mipmaps.
// `selfShadow` (soft with `lightSize`): csm.glsl's csm_shadow dims each direct light.
// Fallback: without WebGL2, on a mesh without TANGENT or the uv set, for an extension that
// breaks its schema (csm_check.js: wrong types, values out of range, an unknown variant) or a
// step map that does not load, the plain PBR material is used (material.userData.csm.fallback
// says why; one console warning per material) and the rest of the scene is drawn.
// Limits: the relief does not move the depth buffer or shadows; the other maps are
// sampled at the hit through their own texture transforms, but a map on another uv set
// than the step map's gets the offset as if its uvs were the step map's; 16-bit step maps
// are sampled as the browser decodes them (8-bit).

import { ShaderChunk, ClampToEdgeWrapping, LinearFilter, RepeatWrapping } from 'three';
import { CSM_GLSL } from './csm_glsl.js';
import { prepareGeometry, uvPlacement } from './csm_geometry.js';
import { checkExtension } from './csm_check.js';

export { prepareGeometry, uvPlacement };

export const EXTENSION = 'EXT_materials_cone_step_mapping';
export const VARIANTS = Object.freeze({
	exact: 'intersect_cone_exact', loop: 'intersect_cone_loop', fixed: 'intersect_cone_fixed',
	parallax: 'intersect_parallax', pom: 'intersect_pom', relief: 'intersect_relief',
	relaxed: 'intersect_cone_relaxed',
});
// Debug views: 0 lit, 1 hit uv (fract, height in blue), 2 iterations heat map,
// 3 raw (hit u, hit v, hit height, status + 1) and 4 raw (iterations, status + 1, 0, 1)
// for float render targets (status: 0 hit, 1 cap, 2 miss; 0 in A = nothing drawn).
// With self-shadowing, for the last direct light shaded (the viewer's sun): 5 raw (light
// direction u, v, up in texture space, hard lit) and 6 raw (soft share, shadow steps, status, 1).
export const DEBUG = { lit: 0, uv: 1, heat: 2, rawUv: 3, rawInfo: 4, rawLight: 5, rawShadow: 6 };
export const DEFAULT_STEPS = 16;  // loop/fixed/pom/relief when the material says 0

export class CSMExtension {

	constructor(parser, options = {}) {
		this.parser = parser;
		this.name = EXTENSION;
		this.options = options;
	}

	async afterRoot(result) {
		const parser = this.parser;
		const defs = parser.json.materials || [];
		const meshes = [];
		for (const s of result.scenes || [result.scene]) s.traverse((o) => { if (o.isMesh) meshes.push(o); });
		const webgl2 = typeof WebGL2RenderingContext !== 'undefined' && this.options.webgl2 !== false;
		const done = new Map();
		for (const mesh of meshes) {
			const list = Array.isArray(mesh.material) ? mesh.material : [mesh.material];
			for (const material of list) {
				const ref = parser.associations.get(material);
				const ext = ref && defs[ref.materials] && (defs[ref.materials].extensions || {})[EXTENSION];
				if (!ext) continue;
				if (!done.has(material)) done.set(material, this._patch(material, ext, webgl2));
				await done.get(material);
				if (material.userData.csm.fallback) continue;
				const placement = material.userData.csm.placement;
				const key = JSON.stringify(placement);
				const made = mesh.geometry.userData.csmPlacement;
				if (made !== undefined && made !== key) mesh.geometry = mesh.geometry.clone();  // shared, placed otherwise
				const why = prepareGeometry(mesh.geometry, placement.texCoord, placement.matrix);
				if (!why) mesh.geometry.userData.csmPlacement = key;
				if (why) {
					console.warn(`${EXTENSION}: mesh ${mesh.name || mesh.uuid}: ${why}; plain PBR there`);
					const plain = material.clone();
					plain.onBeforeCompile = () => {};
					plain.userData = { csm: { ...material.userData.csm, uniforms: null, fallback: why } };
					if (Array.isArray(mesh.material)) mesh.material[mesh.material.indexOf(material)] = plain;
					else mesh.material = plain;
				}
			}
		}
	}

	async _patch(material, ext, webgl2) {
		const { values: v, problems } = checkExtension(ext);
		const info = problems.length ? {} : v.stepMapTexture;
		const placement = uvPlacement(info);
		const csm = {
			extension: ext, texCoord: placement.texCoord, placement, variant: problems.length ? 'exact' : v.variant,
			steps: problems.length ? 0 : v.steps, fallback: null, uniforms: null,
			selfShadow: v.selfShadow === true, lightSize: problems.length ? 0 : v.lightSize,
		};
		material.userData.csm = csm;
		if (!webgl2) { csm.fallback = 'no WebGL2'; return; }
		// one warning per material, the rest of the scene drawn as usual
		const fail = (why) => {
			csm.fallback = why;
			console.warn(`${EXTENSION}: material ${JSON.stringify(material.name || '')}: ${why}; plain PBR there`);
		};
		if (problems.length) return fail(`invalid extension (${problems.join('; ')})`);
		let loaded = null;
		try {
			loaded = await this.parser.getDependency('texture', info.index);
		} catch (e) { /* the loader reports its own error */ }
		if (!loaded) return fail(`step map texture ${info.index} did not load`);
		const tile = v.tile;
		// a copy: the loader's texture may serve other slots; sampled as csm-assets' renderer does
		const stepMap = loaded.clone();
		stepMap.generateMipmaps = false;  // mipmaps would move the surface
		stepMap.minFilter = stepMap.magFilter = LinearFilter;
		stepMap.wrapS = tile[0] ? RepeatWrapping : ClampToEdgeWrapping;
		stepMap.wrapT = tile[1] ? RepeatWrapping : ClampToEdgeWrapping;
		stepMap.needsUpdate = true;
		const [a, b, c, d] = placement.matrix, det = a * d - b * c, k = det ? 1 / det : 0;
		csm.uniforms = {
			stepmap: { value: stepMap },
			// CSM uv offsets back to the mesh's uvs: the inverse of the transform's linear part
			csm_uv_inverse: { value: [d * k, -c * k, -b * k, a * k] },  // column-major mat2
			max_ratio: { value: v.maxRatio },
			tiled: { value: [tile[0] ? 1 : 0, tile[1] ? 1 : 0] },
			conesteps: { value: csm.steps || DEFAULT_STEPS },
			binary_steps: { value: 8 },
			max_iterations: { value: 2048 },
			min_step: { value: v.minStep },
			csm_depth_scale: { value: v.depthScale },
			csm_enabled: { value: true },
			csm_discard: { value: !(tile[0] && tile[1]) },
			csm_debug: { value: DEBUG.lit },
			csm_heat_max: { value: 16 },  // iterations shown red (the exact variant takes 2 to 8 on average)
			selfShadow: { value: csm.selfShadow },  // csm.glsl's switch; the define compiles it in
			lightSize: { value: Math.max(csm.lightSize, 0) },
		};
		if (csm.selfShadow) material.defines = { ...(material.defines || {}), CSM_SELF_SHADOW: '' };
		material.onBeforeCompile = (shader) => csmCompile(shader, material);
		material.customProgramCacheKey = () => `csm:${material.defines.CSM_INTERSECT}:${material.defines.CSM_FIXED_STEPS}:${csm.selfShadow}`;
		setVariant(material, csm.variant, csm.steps);
	}
}

// Switch a CSM material's shader variant and step count (0: the default for loops).
export function setVariant(material, variant, steps = 0) {
	const csm = material.userData.csm;
	if (!csm || !csm.uniforms) return;
	if (!Object.hasOwn(VARIANTS, variant)) throw new Error(`unknown variant ${variant}; known: ${Object.keys(VARIANTS)}`);
	csm.variant = variant;
	csm.steps = steps;
	const n = Math.max(1, Math.min(127, steps || DEFAULT_STEPS));
	csm.uniforms.conesteps.value = steps || DEFAULT_STEPS;
	material.defines = { ...(material.defines || {}), CSM_INTERSECT: VARIANTS[variant], CSM_FIXED_STEPS: n };
	material.needsUpdate = true;
}

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
	float top = texture(stepmap, csm_g_uv).r;
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
		vec4 csm_t = texture(stepmap, csm_uv);
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

function csmCompile(shader, material) {
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
	// vertex shader as mapTransform * uv) get the offset through their own transform
	const transforms = new Set();
	body = body.replace(/\b(texture2D|texture)\(\s*(\w+)\s*,\s*v(\w+)Uv\b/g, (m, fn, map, name) => {
		const transform = name[0].toLowerCase() + name.slice(1) + 'Transform';
		transforms.add(transform);
		return `${fn}( ${map}, (v${name}Uv + mat2(${transform}) * csm_raw_delta)`;
	});
	for (const t of transforms) if (!new RegExp(`uniform\\s+mat3\\s+${t}\\b`).test(head)) head += `uniform mat3 ${t};\n`;
	head += FRAG_HEAD + CSM_GLSL + '\n' + FRAG_SHADOW;
	// each direct light's colour times its visible share (1 without self-shadowing)
	body = body.replace(/\bRE_Direct\(\s*directLight\s*,/g, 'directLight.color *= csm_light_share(directLight.direction); $&');
	const close = body.lastIndexOf('}');
	body = FRAG_BEGIN + body.slice(0, close).replace('//CSM_NORMAL', FRAG_NORMAL) + FRAG_DEBUG + '}\n' + body.slice(close + 1);
	shader.vertexShader = vs;
	shader.fragmentShader = head + 'void main() {' + body;
}
