// csm_settings.js: what both plugins (three.js: csm_plugin.js, Babylon.js: csm_babylon.js) make
// of a material's EXT_materials_cone_step_mapping object, with no engine imports: the checked
// values (csm_check.js), the step map's placement (csm_frame.js), the uniform values of csm.glsl
// and of the fragment glue (csm_frag.js), the variants and which of them draw which step map.

import { EXTENSION, checkExtension } from './csm_check.js';
import { uvInverse, uvPlacement } from './csm_frame.js';

export { EXTENSION };

export const VARIANTS = Object.freeze({
	exact: 'intersect_cone_exact', loop: 'intersect_cone_loop', fixed: 'intersect_cone_fixed',
	parallax: 'intersect_parallax', pom: 'intersect_pom', relief: 'intersect_relief',
	relaxed: 'intersect_cone_relaxed', quadrant: 'intersect_cone_quadrant',
});
// A quadrant step map (two images: stepMapTexture and stepMap2Texture) is drawn by the quadrant
// variant only, and the quadrant variant draws nothing else (see variantsFor, variantRefusal).
export const QUADRANT = 'quadrant';
// Debug views: 0 lit, 1 hit uv (fract, height in blue), 2 iterations heat map,
// 3 raw (hit u, hit v, hit height, status + 1) and 4 raw (iterations, status + 1, 0, 1)
// for float render targets (status: 0 hit, 1 cap, 2 miss; 0 in A = nothing drawn).
// With self-shadowing, for the last direct light shaded (the viewer's sun): 5 raw (light
// direction u, v, up in texture space, hard lit) and 6 raw (soft share, shadow steps, status, 1).
// 7 raw (the material's linear base colour as the relief fetched it, 1), unlit: what `verify
// --distance` compares far away, with the lit colour's pixel-quad share.
export const DEBUG = Object.freeze({ lit: 0, uv: 1, heat: 2, rawUv: 3, rawInfo: 4, rawLight: 5, rawShadow: 6, rawAlbedo: 7 });
export const DEFAULT_STEPS = 16;  // loop/fixed/pom/relief when the material says 0

// A material's settings: { extension, values, problems (empty: usable), placement (uvPlacement
// of the step map), texCoord, variant, steps, selfShadow, lightSize, quadrant (two images),
// fallback: null }. A refused extension keeps exact / 0 steps (what setVariant would say).
export function readSettings(ext) {
	const { values: v, problems } = checkExtension(ext);
	const ok = !problems.length;
	const placement = uvPlacement(ok ? v.stepMapTexture : {});
	return {
		extension: ext, values: v, problems, placement, texCoord: placement.texCoord,
		variant: ok ? v.variant : 'exact', steps: ok ? v.steps : 0, fallback: null,
		selfShadow: v.selfShadow === true, lightSize: ok ? v.lightSize : 0,
		quadrant: ok && v.variant === QUADRANT,
	};
}

// The uniform values (name -> number, boolean or array) of csm.glsl and csm_frag.js for the
// checked settings of readSettings.
export function uniformValues(csm) {
	const v = csm.values, tile = v.tile;
	return {
		csm_uv_inverse: uvInverse(csm.placement.matrix),  // column-major mat2
		max_ratio: v.maxRatio,
		tiled: [tile[0] ? 1 : 0, tile[1] ? 1 : 0],
		conesteps: csm.steps || DEFAULT_STEPS,
		binary_steps: 8,
		max_iterations: 2048,
		min_step: v.minStep,
		csm_depth_scale: v.depthScale,
		csm_enabled: true,
		csm_discard: !(tile[0] && tile[1]),
		csm_debug: DEBUG.lit,
		csm_heat_max: 16,  // iterations shown red (the exact variant takes 2 to 8 on average)
		selfShadow: csm.selfShadow,  // csm.glsl's switch; the define compiles it in
		levels: 0,  // the step map's level chain uploaded as its mip levels: their count (csm_levels.js)
		lightSize: Math.max(csm.lightSize, 0),
	};
}

// The defines a variant and step count compile: { CSM_INTERSECT, CSM_FIXED_STEPS } (steps 0:
// DEFAULT_STEPS, the unrolled count kept in 1..127).
export function variantDefines(variant, steps) {
	return { CSM_INTERSECT: VARIANTS[variant], CSM_FIXED_STEPS: Math.max(1, Math.min(127, steps || DEFAULT_STEPS)) };
}

// The variants that can draw a step map: quadrant alone for a quadrant map (two images), every
// other one for a one-image map.
export function variantsForMap(quadrant) {
	return Object.keys(VARIANTS).filter((name) => (name === QUADRANT) === !!quadrant);
}

// Why `variant` cannot draw material `name`'s step map (quadrant: two images), or null.
export function mapRefusal(name, quadrant, variant) {
	if (variantsForMap(quadrant).includes(variant)) return null;
	const shown = JSON.stringify(name || '');
	return quadrant
		? `material ${shown} holds a quadrant step map (two images); only the quadrant variant draws it, not ${variant}`
		: `material ${shown} holds a one-image step map; the quadrant variant draws quadrant step maps (stepMap2Texture) only`;
}

// A checked variant switch: an Error for an unknown variant or one that cannot draw the map.
export function checkVariant(name, quadrant, variant) {
	if (!Object.hasOwn(VARIANTS, variant)) throw new Error(`unknown variant ${variant}; known: ${Object.keys(VARIANTS)}`);
	const refused = mapRefusal(name, quadrant, variant);
	if (refused) throw new Error(refused);
}
