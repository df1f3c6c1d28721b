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
// and CLAMP_TO_EDGE elsewhere (the extension's `tile`), LINEAR without mipmaps; a step map with a
// level chain (stepMapLevelsTexture, and stepMap2LevelsTexture for a quadrant map's second image:
// csm_levels.js) gets its levels as the texture's mip levels 1..n (LinearMipmapLinear, no generated
// mipmaps) and csm.glsl's `levels` their count, so far pixels march a coarser level. A levels image
// that does not load or is not the documented size: one console warning, level 0 alone.
// `selfShadow` (soft with `lightSize`): csm.glsl's csm_shadow dims each direct light.
// A quadrant step map (variant "quadrant", its second image in stepMap2Texture: csm.glsl's
// stepmap2, sampled as the first) is drawn by the quadrant variant only: setVariant refuses
// any other for it, and the quadrant variant for a one-image map (variantsFor says which fit).
// Fallback: without WebGL2, on a mesh without TANGENT or the uv set, for an extension that
// breaks its schema (csm_check.js: wrong types, values out of range, an unknown variant) or a
// step map that does not load, the plain PBR material is used (material.userData.csm.fallback
// says why; one console warning per material) and the rest of the scene is drawn.
// Limits: the relief does not move the depth buffer or shadows; the other maps are
// sampled at the hit through their own texture transforms, but a map on another uv set
// than the step map's gets the offset as if its uvs were the step map's; 16-bit step maps
// are sampled as the browser decodes them (8-bit).

import { ClampToEdgeWrapping, LinearFilter, LinearMipmapLinearFilter, RepeatWrapping } from 'three';
import { prepareGeometry, uvPlacement } from './csm_geometry.js';
import { DEBUG, DEFAULT_STEPS, EXTENSION, QUADRANT, VARIANTS, checkVariant, mapRefusal, readSettings, uniformValues,
	variantDefines, variantsForMap } from './csm_settings.js';
import { loadLevels } from './csm_levels.js';
import { csmCompile } from './csm_shader.js';

export { DEBUG, DEFAULT_STEPS, EXTENSION, QUADRANT, VARIANTS, prepareGeometry, uvPlacement };

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
		const csm = readSettings(ext);
		const { values: v, problems, placement } = csm;
		const info = problems.length ? {} : v.stepMapTexture;
		csm.uniforms = null;
		material.userData.csm = csm;
		if (!webgl2) { csm.fallback = 'no WebGL2'; return; }
		// one warning per material, the rest of the scene drawn as usual
		const fail = (why) => {
			csm.fallback = why;
			console.warn(`${EXTENSION}: material ${JSON.stringify(material.name || '')}: ${why}; plain PBR there`);
		};
		if (problems.length) return fail(`invalid extension (${problems.join('; ')})`);
		const load = async (index) => {
			try { return await this.parser.getDependency('texture', index); } catch (e) { return null; }  // the loader reports its own error
		};
		const info2 = csm.quadrant ? v.stepMap2Texture : null;
		const [loaded, loaded2] = await Promise.all([load(info.index), info2 && load(info2.index)]);
		if (!loaded) return fail(`step map texture ${info.index} did not load`);
		if (info2 && !loaded2) return fail(`second step map texture (stepMap2Texture) ${info2.index} did not load`);
		const size = (t) => (t.image && t.image.width !== undefined ? `${t.image.width}x${t.image.height}` : null);
		if (info2 && size(loaded) !== size(loaded2)) {
			return fail(`the step map's two images differ in size (${size(loaded)}, stepMap2Texture ${size(loaded2)})`);
		}
		const tile = v.tile;
		const decode = async (levelsInfo) => { const t = await load(levelsInfo.index); return t && t.image; };  // ImageBitmapLoader: raw
		const dims = [loaded, loaded2].filter(Boolean).map((t) => [t.image.width, t.image.height]);
		const [levels, levels2] = await loadLevels(v, csm.quadrant, dims, decode,
			(why) => console.warn(`${EXTENSION}: material ${JSON.stringify(material.name || '')}: ${why}`));
		csm.uniforms = { stepmap: { value: stepMapCopy(loaded, tile, levels) } };
		for (const [name, value] of Object.entries(uniformValues(csm))) csm.uniforms[name] = { value };
		csm.uniforms.levels.value = levels.length;
		if (info2) csm.uniforms.stepmap2 = { value: stepMapCopy(loaded2, tile, levels2) };  // csm.glsl's second image
		if (csm.selfShadow) material.defines = { ...(material.defines || {}), CSM_SELF_SHADOW: '' };
		if (csm.quadrant) material.defines = { ...(material.defines || {}), CSM_QUADRANT_MAPS: '' };
		material.onBeforeCompile = (shader) => csmCompile(shader, material);
		material.customProgramCacheKey = () => `csm:${material.defines.CSM_INTERSECT}:${material.defines.CSM_FIXED_STEPS}:${csm.selfShadow}:${csm.quadrant}`;
		setVariant(material, csm.variant, csm.steps);
	}
}

// A copy of a loaded step map image (the loader's texture may serve other slots), sampled as
// csm-assets' renderer does: LINEAR without mipmaps (three's own would average the cones), or with
// the map's level chain `levels` (ImageBitmaps, level 1 first) as mip levels 1..n,
// LinearMipmapLinear; REPEAT on tiled axes and CLAMP_TO_EDGE on the others; its colour space as
// the loader left it (none).
function stepMapCopy(loaded, tile, levels = []) {
	const t = loaded.clone();
	t.generateMipmaps = false;
	t.mipmaps = levels.length ? [t.image, ...levels] : [];
	t.magFilter = LinearFilter;
	t.minFilter = levels.length ? LinearMipmapLinearFilter : LinearFilter;
	t.wrapS = tile[0] ? RepeatWrapping : ClampToEdgeWrapping;
	t.wrapT = tile[1] ? RepeatWrapping : ClampToEdgeWrapping;
	t.needsUpdate = true;
	return t;
}

// The variants that can draw a CSM material's step map: quadrant alone for a quadrant map (two
// images), every other one for a one-image map.
export function variantsFor(material) {
	return variantsForMap(material.userData.csm && material.userData.csm.quadrant);
}

// Why `variant` cannot draw the material's step map, or null (an unknown variant is not asked here).
export function variantRefusal(material, variant) {
	return mapRefusal(material.name, material.userData.csm && material.userData.csm.quadrant, variant);
}

// Switch a CSM material's shader variant and step count (0: the default for loops). An unknown
// variant, or one that cannot draw the material's step map (variantRefusal), is an Error and
// changes nothing. A material on the PBR fallback keeps it (nothing to switch).
export function setVariant(material, variant, steps = 0) {
	const csm = material.userData.csm;
	if (!csm) return;
	checkVariant(material.name, csm.quadrant, variant);
	if (!csm.uniforms) return;
	csm.variant = variant;
	csm.steps = steps;
	csm.uniforms.conesteps.value = steps || DEFAULT_STEPS;
	material.defines = { ...(material.defines || {}), ...variantDefines(variant, steps) };
	material.needsUpdate = true;
}
