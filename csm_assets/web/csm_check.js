// csm_check.js: checks a material's EXT_materials_cone_step_mapping object against the
// extension's JSON schema (csm_schema.js, generated from docs/) before the plugin uses it.
//
// checkExtension(ext) -> { values, problems }: values holds every property of the schema
// (the material's own value, else the schema's default), problems lists what is wrong
// (empty: all good). Only own properties are read (Object.hasOwn), so a value never comes
// from Object.prototype and a name such as "constructor", "toString" or "__proto__" is a
// string like any other (refused by the variant's enum). The subset of JSON schema checked:
// type (object, array, string, boolean, number: finite, integer), enum, minimum, maximum,
// exclusiveMinimum, minItems, maxItems, items, properties, required, and $ref to the schema's
// own $defs (the two step maps' textureInfo). The step maps'
// textureInfos may carry KHR_texture_transform, checked too (glTF's own schema for it).
// Beyond the schema: a number past 32-bit floats (what the shader holds) is refused;
// stepMap2Texture is there exactly when variant is quadrant, with stepMapTexture's texCoord
// (and KHR_texture_transform, if it carries one).

import { SCHEMA } from './csm_schema.js';

export const EXTENSION = 'EXT_materials_cone_step_mapping';

const TRANSFORM = 'KHR_texture_transform';
const NUMBER2 = { type: 'array', items: { type: 'number' }, minItems: 2, maxItems: 2 };
export const TRANSFORM_SCHEMA = Object.freeze({
	type: 'object',
	properties: { offset: NUMBER2, rotation: { type: 'number' }, scale: NUMBER2,
		texCoord: { type: 'integer', minimum: 0 } },
});

const FLOAT32_MAX = 3.4028234663852886e38;  // the shader's floats: a number past it is refused (beyond the schema)
const own = (o, k) => Object.prototype.hasOwnProperty.call(o, k);
const isObject = (v) => typeof v === 'object' && v !== null && !Array.isArray(v);
const show = (v) => { try { return JSON.stringify(v).slice(0, 60); } catch (e) { return String(typeof v); } };

function isType(v, type) {
	switch (type) {
		case 'object': return isObject(v);
		case 'array': return Array.isArray(v);
		case 'string': return typeof v === 'string';
		case 'boolean': return typeof v === 'boolean';
		case 'number': return typeof v === 'number' && Number.isFinite(v);
		case 'integer': return typeof v === 'number' && Number.isInteger(v);
		default: return false;
	}
}

// Schema s with its $ref (only "#/$defs/<name>", this schema's own) replaced by what it names.
function resolved(s) {
	if (!own(s, '$ref')) return s;
	const name = /^#\/\$defs\/(\w+)$/.exec(s.$ref)?.[1];
	if (!name || !own(SCHEMA.$defs, name)) throw new Error(`csm_schema.js: cannot resolve $ref ${s.$ref}`);
	return resolved(SCHEMA.$defs[name]);
}

// What is wrong with value v at path `where` under schema s (pushed onto problems).
function check(v, s, where, problems) {
	s = resolved(s);
	if (own(s, 'type') && !isType(v, s.type)) {
		problems.push(`${where} must be ${s.type === 'integer' ? 'an integer' : `a ${s.type}`}, got ${show(v)}`);
		return;
	}
	if (own(s, 'enum') && !s.enum.some((e) => e === v)) problems.push(`${where} ${show(v)} is none of ${s.enum.join(', ')}`);
	if (own(s, 'minimum') && v < s.minimum) problems.push(`${where} ${v} is below ${s.minimum}`);
	if (own(s, 'maximum') && v > s.maximum) problems.push(`${where} ${v} is above ${s.maximum}`);
	if (own(s, 'exclusiveMinimum') && !(v > s.exclusiveMinimum)) problems.push(`${where} ${v} must be above ${s.exclusiveMinimum}`);
	if (typeof v === 'number' && Math.abs(v) > FLOAT32_MAX) problems.push(`${where} ${v} is beyond the shader's 32-bit floats`);
	if (Array.isArray(v)) {
		if (own(s, 'minItems') && v.length < s.minItems) problems.push(`${where} has ${v.length} items, fewer than ${s.minItems}`);
		if (own(s, 'maxItems') && v.length > s.maxItems) problems.push(`${where} has ${v.length} items, more than ${s.maxItems}`);
		if (own(s, 'items')) v.forEach((x, i) => check(x, s.items, `${where}[${i}]`, problems));
	}
	if (isObject(v) && own(s, 'properties')) {
		for (const name of s.required || []) if (!own(v, name)) problems.push(`${where}.${name} is missing`);
		for (const name of Object.keys(s.properties)) {
			if (own(v, name)) check(v[name], s.properties[name], `${where}.${name}`, problems);
		}
	}
}

// The checked values and the problems of a material's extension object (see the top).
export function checkExtension(ext) {
	const problems = [], values = {};
	if (!isObject(ext)) return { values, problems: [`the extension must be an object, got ${show(ext)}`] };
	for (const name of SCHEMA.required) if (!own(ext, name)) problems.push(`${name} is missing`);
	for (const name of Object.keys(SCHEMA.properties)) {
		const s = SCHEMA.properties[name];
		if (own(ext, name)) {
			const before = problems.length;
			check(ext[name], s, name, problems);
			if (problems.length === before) values[name] = ext[name];
		} else if (own(s, 'default')) {
			values[name] = structuredClone(s.default);
		}
	}
	for (const name of ['stepMapTexture', 'stepMap2Texture']) {
		const info = values[name];
		if (info && own(info, 'extensions')) {
			if (!isObject(info.extensions)) problems.push(`${name}.extensions must be an object`);
			else if (own(info.extensions, TRANSFORM)) {
				check(info.extensions[TRANSFORM], TRANSFORM_SCHEMA, `${name}.extensions.${TRANSFORM}`, problems);
			}
		}
	}
	if (!problems.length) quadrantProblems(values, problems);
	return { values, problems };
}

// A quadrant step map is two images: stepMap2Texture is there exactly when variant is
// quadrant, and is sampled where stepMapTexture is (the same texCoord; a KHR_texture_transform
// on it, if any, the same as the first's).
function quadrantProblems(values, problems) {
	const quadrant = values.variant === 'quadrant', second = values.stepMap2Texture;
	if (quadrant && !second) {
		problems.push('variant quadrant draws a quadrant step map, two images: stepMap2Texture is missing');
	} else if (!quadrant && second) {
		problems.push(`stepMap2Texture (a quadrant step map's second image) is drawn only by variant quadrant, not ${values.variant}`);
	} else if (second) {
		const first = values.stepMapTexture, t1 = first.texCoord ?? 0, t2 = second.texCoord ?? 0;
		if (t1 !== t2) problems.push(`stepMap2Texture.texCoord ${t2} is not stepMapTexture's ${t1}`);
		const place = (info) => {  // the transform as text, its keys in one order
			const t = (isObject(info.extensions) && info.extensions[TRANSFORM]) || {};
			return JSON.stringify(t, Object.keys(t).sort());
		};
		if (isObject(second.extensions) && own(second.extensions, TRANSFORM) && place(second) !== place(first)) {
			problems.push(`stepMap2Texture's ${TRANSFORM} is not stepMapTexture's (both images are sampled at the same uv)`);
		}
	}
}
