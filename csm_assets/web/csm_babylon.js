// csm_babylon.js: a Babylon.js glTF loader extension for EXT_materials_cone_step_mapping
// (csm-assets), with a material plugin that splices the project's csm.glsl march into the
// loader's PBRMaterial.
//
//   import { SceneLoader } from '@babylonjs/core';  // any Babylon.js app
//   import { registerCSMExtension } from '@csm-assets/babylon';
//   registerCSMExtension();  // then load glTF as usual: SceneLoader.ImportMeshAsync, LoadAssetContainerAsync, ...
//
// Needs @babylonjs/core and @babylonjs/loaders 9 (tested with 9.x) and a WebGL2 engine (GLSL).
// Each material carrying the extension keeps its PBRMaterial (base colour, metal/rough, normal
// and emissive maps, texture transforms, both uv sets); a CSMMaterialPlugin traces the view ray
// through the step map (csm.glsl, the material's own variant and steps) and samples every map at
// the hit uv through its own texture matrix (csm_babylon_shader.js). The settings, the placement
// (texCoord and KHR_texture_transform of the step map), the frame (the glTF TANGENT, the world
// size per uv unit per vertex) and the schema check are csm_settings.js, csm_frame.js and
// csm_check.js: the three.js plugin's own code. The step map is sampled LINEAR without mipmaps,
// REPEAT on the axes `tile` says, CLAMP_TO_EDGE on the others; one with a level chain
// (stepMapLevelsTexture, stepMap2LevelsTexture: csm_levels.js) gets its levels as the texture's mip
// levels 1..n (engine.updateTextureData per level, TRILINEAR) and csm.glsl's `levels` their count;
// a levels image that does not load or is not the documented size: one console warning, level 0
// alone. selfShadow (and lightSize): each
// point, spot and directional light is dimmed by csm.glsl's csm_shadow.
// Fallback: without WebGL2, for a material the loader did not make a PBRMaterial, an extension
// that breaks its schema (one console warning per material), a step map that does not load or
// whose two images differ in size, the plain PBR material is drawn; a mesh without TANGENT or
// the step map's uv set is drawn plain too (one warning per mesh). material.metadata.csm holds
// the settings and `fallback` (why, or null).
// Limits: perspective cameras only (an orthographic camera's rays are taken as from its
// position); the relief does not move the depth buffer or shadow maps; maps other than Babylon's
// PBR ones listed in csm_babylon_shader.js get the offset as if their uvs were the step map's.

import { MaterialPluginBase } from '@babylonjs/core/Materials/materialPluginBase.js';
import { PBRMaterial } from '@babylonjs/core/Materials/PBR/pbrMaterial.js';
import { Texture } from '@babylonjs/core/Materials/Textures/texture.js';
import { GLTFLoader } from '@babylonjs/loaders/glTF/2.0/glTFLoader.js';
import { registerGLTFExtension, unregisterGLTFExtension } from '@babylonjs/loaders/glTF/2.0/glTFLoaderExtensionRegistry.js';
import { frameArrays } from './csm_frame.js';
import { decodeRaw, loadLevels } from './csm_levels.js';
import { DEBUG, DEFAULT_STEPS, EXTENSION, QUADRANT, VARIANTS, checkVariant, readSettings, uniformValues,
	variantDefines, variantsForMap } from './csm_settings.js';
import { FIXED_BITS, customCode, fixedBits } from './csm_babylon_shader.js';

export { DEBUG, DEFAULT_STEPS, EXTENSION, QUADRANT, VARIANTS };

const UV_KINDS = ['uv', 'uv2', 'uv3', 'uv4', 'uv5', 'uv6'];
const ATTRIBUTES = ['csmTangent', 'csmUv', 'csmDpdu', 'csmDpdv'];
const UNIFORMS = ['max_ratio', 'tiled', 'conesteps', 'binary_steps', 'max_iterations', 'min_step', 'csm_depth_scale',
	'csm_enabled', 'csm_discard', 'csm_debug', 'csm_heat_max', 'csm_uv_inverse', 'selfShadow', 'lightSize', 'levels'];

// The material plugin: the relief on a PBRMaterial, per mesh where the mesh has the frame inputs
// (prepareMesh). csm: readSettings' object with `uniforms` (uniformValues); stepmap, stepmap2: textures.
export class CSMMaterialPlugin extends MaterialPluginBase {
	constructor(material, csm, stepmap, stepmap2 = null) {
		const defines = { CSM: false, CSM_INTERSECT: VARIANTS.exact, CSM_SELF_SHADOW: false, CSM_QUADRANT_MAPS: false,
			CSM_FIXED_STEPS: DEFAULT_STEPS, ...fixedBits(DEFAULT_STEPS) };
		super(material, 'CSM', 200, defines, true, true);
		this.csm = csm;
		this.stepmap = stepmap;
		this.stepmap2 = stepmap2;
	}

	getClassName() { return 'CSMMaterialPlugin'; }

	isCompatible(shaderLanguage) { return shaderLanguage === 0; }  // GLSL (WebGL2), not WGSL

	prepareDefines(defines, scene, mesh) {
		const on = !!(mesh && ATTRIBUTES.every((k) => mesh.isVerticesDataPresent(k)));
		const { CSM_INTERSECT, CSM_FIXED_STEPS } = variantDefines(this.csm.variant, this.csm.steps);
		Object.assign(defines, { CSM: on, CSM_INTERSECT, CSM_SELF_SHADOW: on && this.csm.selfShadow,
			CSM_QUADRANT_MAPS: on && this.csm.quadrant, CSM_FIXED_STEPS, ...fixedBits(CSM_FIXED_STEPS) });
	}

	isReadyForSubMesh() {
		return this.stepmap.isReady() && (!this.stepmap2 || this.stepmap2.isReady());
	}

	getAttributes(attributes, scene, mesh) {
		if (ATTRIBUTES.every((k) => mesh.isVerticesDataPresent(k))) attributes.push(...ATTRIBUTES);
	}

	getSamplers(samplers) { samplers.push('stepmap', 'stepmap2'); }

	getUniforms() { return { ubo: UNIFORMS.map((name) => ({ name })) }; }  // loose uniforms (csm.glsl declares them)

	getCustomCode(shaderType) { return customCode(shaderType); }

	bindForSubMesh(uniformBuffer, scene, engine, subMesh) {
		const effect = subMesh.effect, u = this.csm.uniforms;
		if (!effect) return;
		effect.setTexture('stepmap', this.stepmap);
		if (this.stepmap2) effect.setTexture('stepmap2', this.stepmap2);
		for (const name of ['max_ratio', 'min_step', 'csm_depth_scale', 'csm_heat_max', 'lightSize']) effect.setFloat(name, u[name]);
		for (const name of ['conesteps', 'binary_steps', 'max_iterations', 'csm_debug', 'levels']) effect.setInt(name, u[name]);
		for (const name of ['csm_enabled', 'csm_discard', 'selfShadow']) effect.setBool(name, u[name]);
		effect.setInt2('tiled', u.tiled[0], u.tiled[1]);
		effect.setMatrix2x2('csm_uv_inverse', u.csm_uv_inverse);
	}

	hasTexture(texture) { return texture === this.stepmap || texture === this.stepmap2; }

	getActiveTextures(list) { list.push(this.stepmap, ...(this.stepmap2 ? [this.stepmap2] : [])); }

	// Recompile with the csm settings' variant and steps (after setVariant).
	update() { this.markAllDefinesAsDirty(); }
}

// The per-vertex frame inputs of the relief on a Babylon mesh (csm_frame.js): csmTangent,
// csmUv, csmDpdu, csmDpdv. Returns why not, or null when done. A geometry shared with a
// material placed otherwise is made unique first.
export function prepareMesh(mesh, placement) {
	const tangent = mesh.getVerticesData('tangent'), uv = mesh.getVerticesData(UV_KINDS[placement.texCoord]);
	if (!tangent) return 'no TANGENT';
	if (!uv) return `no TEXCOORD_${placement.texCoord}`;
	const key = JSON.stringify(placement);
	const meta = mesh.geometry && mesh.geometry.metadata;
	if (meta && meta.csmPlacement === key) return null;
	if (meta && meta.csmPlacement !== undefined) mesh.makeGeometryUnique();
	const frame = frameArrays(mesh.getVerticesData('position'), uv, mesh.getIndices(), placement.matrix);
	mesh.setVerticesData('csmTangent', tangent, false, 4);
	mesh.setVerticesData('csmUv', frame.uv, false, 2);
	mesh.setVerticesData('csmDpdu', frame.dpdu, false, 3);
	mesh.setVerticesData('csmDpdv', frame.dpdv, false, 3);
	mesh.geometry.metadata = { ...(mesh.geometry.metadata || {}), csmPlacement: key };
	return null;
}

// The glTF loader extension (registerCSMExtension registers it by the extension's name).
export class CSMLoaderExtension {
	constructor(loader, options = {}) {
		this.name = EXTENSION;
		this.order = 200;
		this._loader = loader;
		this.options = options;
		this.enabled = loader.isExtensionUsed(EXTENSION);
		this._patched = [];  // [babylon material, its settings]
	}

	dispose() { this._loader = null; this._patched = []; }

	loadMaterialPropertiesAsync(context, material, babylonMaterial) {
		return GLTFLoader.LoadExtensionAsync(context, material, this.name, async (extContext, ext) => {
			await Promise.all([this._loader.loadMaterialPropertiesAsync(context, material, babylonMaterial),
				this._patch(extContext, ext, babylonMaterial, material.index)]);
		});
	}

	// every mesh drawn with a patched material gets its frame inputs, or is drawn plain
	onReady() {
		for (const [material, csm] of this._patched) {
			if (csm.fallback) continue;
			for (const mesh of material.getBindedMeshes()) {
				const why = prepareMesh(mesh, csm.placement);
				if (why) console.warn(`${EXTENSION}: mesh ${mesh.name}: ${why}; plain PBR there`);
			}
		}
	}

	async _patch(context, ext, material, index) {
		const csm = readSettings(ext);
		csm.uniforms = null;
		csm.index = index;  // the glTF material's
		material.metadata = { ...(material.metadata || {}), csm };
		this._patched.push([material, csm]);
		const fail = (why) => {  // one warning per material, the rest of the scene drawn as usual
			csm.fallback = why;
			console.warn(`${EXTENSION}: material ${JSON.stringify(material.name || '')}: ${why}; plain PBR there`);
		};
		const engine = material.getScene().getEngine();
		if (this.options.webgl2 === false || engine.webGLVersion < 2 || engine.isWebGPU) { csm.fallback = 'no WebGL2'; return; }
		if (!(material instanceof PBRMaterial)) return fail(`the loader made a ${material.getClassName()}, not a PBRMaterial`);
		if (csm.problems.length) return fail(`invalid extension (${csm.problems.join('; ')})`);
		const v = csm.values;
		const load = async (key, info) => {
			try {
				return await this._loader.loadTextureInfoAsync(`${context}/${key}`, { ...info, nonColorData: true }, () => {});
			} catch (e) { return null; }  // the loader reports its own error
		};
		const info2 = csm.quadrant ? v.stepMap2Texture : null;
		const [map, map2] = await Promise.all([load('stepMapTexture', v.stepMapTexture),
			info2 && load('stepMap2Texture', info2)]);
		if (!map) return fail(`step map texture ${v.stepMapTexture.index} did not load`);
		if (info2 && !map2) return fail(`second step map texture (stepMap2Texture) ${info2.index} did not load`);
		await Promise.all([map, map2].filter(Boolean).map(ready));
		const size = (t) => { const s = t.getSize(); return `${s.width}x${s.height}`; };
		if (map2 && size(map) !== size(map2)) {
			return fail(`the step map's two images differ in size (${size(map)}, stepMap2Texture ${size(map2)})`);
		}
		const gltf = this._loader.gltf;
		const decode = async (info) => {  // the levels image's bytes (a file or a bufferView), decoded as data
			const source = ((gltf.textures || [])[info.index] || {}).source, image = (gltf.images || [])[source];
			try { return image ? await decodeRaw(await this._loader.loadImageAsync(`/images/${source}`, image), image.mimeType) : null; } catch (e) { return null; }
		};
		const dims = [map, map2].filter(Boolean).map((t) => [t.getSize().width, t.getSize().height]);
		const chains = await loadLevels(v, csm.quadrant, dims, decode, (why) => console.warn(
			`${EXTENSION}: material ${JSON.stringify(material.name || '')}: ${why}`));
		[map, map2].forEach((t, i) => t && sampleAsStepMap(t, v.tile, chains[i]));
		csm.uniforms = uniformValues(csm);
		csm.uniforms.levels = chains[0].length;
		csm.plugin = new CSMMaterialPlugin(material, csm, map, map2);
	}
}

// Resolves once the texture's image is there (Babylon textures load asynchronously).
function ready(texture) {
	if (texture.isReady()) return Promise.resolve();
	return new Promise((resolve) => {
		if (texture.onLoadObservable) texture.onLoadObservable.addOnce(() => resolve());
		else resolve();
	});
}

// As csm-assets' renderer samples a step map: LINEAR without mipmaps (Babylon's own would average
// the cones), or with the map's level chain `levels` (ImageBitmaps, level 1 first) as mip levels
// 1..n, TRILINEAR (gl.generateMipmap allocates the levels, each then overwritten with the chain's);
// without anisotropic filtering (Babylon's default of 4 blurs the slopes along a long footprint, as
// three.js' plugin does not); REPEAT on tiled axes and CLAMP_TO_EDGE on the others.
function sampleAsStepMap(texture, tile, levels) {
	if (levels.length) {
		const engine = texture.getScene().getEngine(), internal = texture.getInternalTexture();
		engine.updateTextureSamplingMode(Texture.TRILINEAR_SAMPLINGMODE, internal, true);
		levels.forEach((img, k) => engine.updateTextureData(internal, img, 0, 0, img.width, img.height, 0, k + 1, false));
	} else {
		texture.updateSamplingMode(Texture.LINEAR_LINEAR);
	}
	texture.anisotropicFilteringLevel = 1;
	texture.wrapU = tile[0] ? Texture.WRAP_ADDRESSMODE : Texture.CLAMP_ADDRESSMODE;
	texture.wrapV = tile[1] ? Texture.WRAP_ADDRESSMODE : Texture.CLAMP_ADDRESSMODE;
}

// Register the loader extension for every glTF loaded afterwards (options: { webgl2: false }
// forces the fallback). Returns a function that unregisters it.
export function registerCSMExtension(options = {}) {
	registerGLTFExtension(EXTENSION, true, (loader) => new CSMLoaderExtension(loader, options));
	return () => unregisterGLTFExtension(EXTENSION);
}

// The CSM settings of a Babylon material (material.metadata.csm), or null.
export const settingsOf = (material) => (material && material.metadata && material.metadata.csm) || null;

// The variants that can draw a CSM material's step map (quadrant alone for a quadrant map).
export const variantsFor = (material) => variantsForMap(settingsOf(material) && settingsOf(material).quadrant);

// Switch a CSM material's variant and steps (0: the default for loops); an Error for an unknown
// variant or one that cannot draw its step map. A material on the fallback keeps it.
export function setVariant(material, variant, steps = 0) {
	const csm = settingsOf(material);
	if (!csm) return;
	checkVariant(material.name, csm.quadrant, variant);
	if (!csm.plugin) return;
	csm.variant = variant;
	csm.steps = steps;
	csm.uniforms.conesteps = steps || DEFAULT_STEPS;
	csm.plugin.update();
}

export { FIXED_BITS };
