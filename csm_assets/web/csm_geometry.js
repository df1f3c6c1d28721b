// csm_geometry.js: the per-vertex tangent-frame inputs of csm_plugin.js's shader on a three.js
// geometry (the math, shared with the Babylon.js plugin, is csm_frame.js's).

import { BufferAttribute } from 'three';
import { frameArrays, uvPlacement } from './csm_frame.js';

export { uvPlacement };

const UV_NAMES = ['uv', 'uv1', 'uv2', 'uv3'];

// Per-vertex tangent frame inputs of the relief: csmTangent (the glTF TANGENT), csmUv (the
// step map's uv set through its texture transform ``matrix``, see uvPlacement) and csmDpdu /
// csmDpdv (object-space position per CSM uv unit, area-weighted over the triangles around
// each vertex). Returns why not, or null when done.
export function prepareGeometry(geometry, texCoord = 0, matrix = [1, 0, 0, 1, 0, 0]) {
	const a = geometry.attributes;
	const raw = a[UV_NAMES[texCoord]];
	if (!a.tangent) return 'no TANGENT';
	if (!raw) return `no TEXCOORD_${texCoord}`;
	if (a.csmDpdu) return null;
	const pos = a.position, n = pos.count;
	const position = new Float64Array(3 * n), uv = new Float64Array(2 * n);
	for (let i = 0; i < n; i++) {  // getX: interleaved and normalized integers come back as floats
		position[3 * i] = pos.getX(i); position[3 * i + 1] = pos.getY(i); position[3 * i + 2] = pos.getZ(i);
		uv[2 * i] = raw.getX(i); uv[2 * i + 1] = raw.getY(i);
	}
	const idx = geometry.index;
	const index = idx ? Array.from({ length: idx.count }, (_, k) => idx.getX(k)) : null;
	const frame = frameArrays(position, uv, index, matrix);
	geometry.setAttribute('csmDpdu', new BufferAttribute(frame.dpdu, 3));
	geometry.setAttribute('csmDpdv', new BufferAttribute(frame.dpdv, 3));
	geometry.setAttribute('csmTangent', a.tangent);
	geometry.setAttribute('csmUv', new BufferAttribute(frame.uv, 2));
	return null;
}
