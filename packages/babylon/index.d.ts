// Type declarations of csm-assets-babylon (dist/csm_babylon.js): a Babylon.js glTF loader
// extension and material plugin for EXT_materials_cone_step_mapping.
import type { MaterialPluginBase } from '@babylonjs/core/Materials/materialPluginBase.js';
import type { Material } from '@babylonjs/core/Materials/material.js';
import type { PBRMaterial } from '@babylonjs/core/Materials/PBR/pbrMaterial.js';
import type { BaseTexture } from '@babylonjs/core/Materials/Textures/baseTexture.js';
import type { Mesh } from '@babylonjs/core/Meshes/mesh.js';
import type { GLTFLoader } from '@babylonjs/loaders/glTF/2.0/glTFLoader.js';
import type { IGLTFLoaderExtension } from '@babylonjs/loaders/glTF/2.0/glTFLoaderExtension.js';

export type Variant = 'exact' | 'loop' | 'fixed' | 'parallax' | 'pom' | 'relief' | 'relaxed' | 'quadrant';
type Placement = { texCoord: number; matrix: [number, number, number, number, number, number] };

export const EXTENSION: 'EXT_materials_cone_step_mapping';
export const VARIANTS: Readonly<Record<Variant, string>>;
export const QUADRANT: 'quadrant';
/** Debug views (settings.uniforms.csm_debug): lit, hit uv, heat map, raw float views. */
export const DEBUG: Readonly<{ lit: 0; uv: 1; heat: 2; rawUv: 3; rawInfo: 4; rawLight: 5; rawShadow: 6; rawAlbedo: 7 }>;
export const DEFAULT_STEPS: number;
export const FIXED_BITS: number[];

/** What the extension keeps in material.metadata.csm. */
export interface CSMSettings {
	extension: unknown;
	index: number;
	variant: Variant;
	steps: number;
	texCoord: number;
	placement: Placement;
	selfShadow: boolean;
	lightSize: number;
	quadrant: boolean;
	/** Why the plain PBR material is drawn, or null. */
	fallback: string | null;
	/** The shader's uniform values (bound on each draw), null on the fallback. */
	uniforms: Record<string, number | boolean | number[]> | null;
	plugin?: CSMMaterialPlugin;
}

export interface CSMExtensionOptions {
	/** false: draw the plain PBR material (as without WebGL2). */
	webgl2?: boolean;
}

/** Register the loader extension for every glTF loaded afterwards; returns the unregistering function. */
export function registerCSMExtension(options?: CSMExtensionOptions): () => boolean;

export class CSMLoaderExtension implements IGLTFLoaderExtension {
	constructor(loader: GLTFLoader, options?: CSMExtensionOptions);
	readonly name: 'EXT_materials_cone_step_mapping';
	enabled: boolean;
	order: number;
	dispose(): void;
}

export class CSMMaterialPlugin extends MaterialPluginBase {
	constructor(material: PBRMaterial, csm: CSMSettings, stepmap: BaseTexture, stepmap2?: BaseTexture | null);
	csm: CSMSettings;
	/** Recompile with the settings' variant and steps. */
	update(): void;
}

/** The relief's per-vertex inputs on a mesh; why not, or null. */
export function prepareMesh(mesh: Mesh, placement: Placement): string | null;
/** The CSM settings of a material, or null. */
export function settingsOf(material: Material | null | undefined): CSMSettings | null;
export function variantsFor(material: Material): Variant[];
/** Switch a CSM material's variant and steps (0: the default); throws for one that cannot draw its map. */
export function setVariant(material: Material, variant: Variant, steps?: number): void;
