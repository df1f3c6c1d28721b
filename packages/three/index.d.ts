// Type declarations of csm-assets-three (dist/csm_plugin.js): a three.js GLTFLoader plugin for
// EXT_materials_cone_step_mapping.
import type { BufferGeometry, Material } from 'three';
import type { GLTFLoaderPlugin, GLTFParser } from 'three/examples/jsm/loaders/GLTFLoader.js';

export type Variant = 'exact' | 'loop' | 'fixed' | 'parallax' | 'pom' | 'relief' | 'relaxed' | 'quadrant';

/** The extension's name, EXT_materials_cone_step_mapping. */
export const EXTENSION: 'EXT_materials_cone_step_mapping';
/** Each variant's csm.glsl function. */
export const VARIANTS: Readonly<Record<Variant, string>>;
export const QUADRANT: 'quadrant';
/** Debug views (the csm_debug uniform): lit, hit uv, heat map, raw float views. */
export const DEBUG: Readonly<{ lit: 0; uv: 1; heat: 2; rawUv: 3; rawInfo: 4; rawLight: 5; rawShadow: 6; rawAlbedo: 7 }>;
/** Steps of loop/fixed/pom/relief when the material says 0. */
export const DEFAULT_STEPS: number;

/** What the plugin keeps in material.userData.csm. */
export interface CSMSettings {
	extension: unknown;
	variant: Variant;
	steps: number;
	texCoord: number;
	placement: { texCoord: number; matrix: [number, number, number, number, number, number] };
	selfShadow: boolean;
	lightSize: number;
	quadrant: boolean;
	/** Why the plain PBR material is drawn, or null. */
	fallback: string | null;
	/** The shader's uniforms ({ value }), null on the fallback. */
	uniforms: Record<string, { value: unknown }> | null;
}

export interface CSMExtensionOptions {
	/** false: draw the plain PBR material (as without WebGL2). */
	webgl2?: boolean;
}

/** The GLTFLoader plugin: loader.register((parser) => new CSMExtension(parser)). */
export class CSMExtension implements GLTFLoaderPlugin {
	constructor(parser: GLTFParser, options?: CSMExtensionOptions);
	readonly name: 'EXT_materials_cone_step_mapping';
	afterRoot(result: unknown): Promise<void>;
}

/** The variants that can draw a CSM material's step map (quadrant alone for a quadrant map). */
export function variantsFor(material: Material): Variant[];
/** Why `variant` cannot draw the material's step map, or null. */
export function variantRefusal(material: Material, variant: Variant): string | null;
/** Switch a CSM material's variant and steps (0: the default); throws for one that cannot draw its map. */
export function setVariant(material: Material, variant: Variant, steps?: number): void;
/** The step map's placement of a textureInfo (texCoord and KHR_texture_transform). */
export function uvPlacement(info?: object): { texCoord: number; matrix: [number, number, number, number, number, number] };
/** Add the relief's per-vertex inputs to a geometry; why not, or null. */
export function prepareGeometry(geometry: BufferGeometry, texCoord?: number,
	matrix?: [number, number, number, number, number, number]): string | null;
