// csm_geometry.js: where the relief of EXT_materials_cone_step_mapping lies on a mesh
// (csm-assets' three.js plugin, csm_plugin.js): the step map's uv placement and the
// per-vertex tangent-frame inputs the plugin's shader reads.

import { BufferAttribute } from 'three';

const UV_NAMES = ['uv', 'uv1', 'uv2', 'uv3'];
const TRANSFORM = 'KHR_texture_transform';

// The placement of a textureInfo: { texCoord, matrix: [a, b, c, d, ox, oy] } with the
// KHR_texture_transform u' = a u + b v + ox, v' = c u + d v + oy (scale, then rotation,
// then offset, as glTF defines it), the identity without the extension.
export function uvPlacement(info = {}) {
	const t = (info.extensions || {})[TRANSFORM];
	const texCoord = t && t.texCoord !== undefined ? t.texCoord : (info.texCoord || 0);
	if (!t) return { texCoord, matrix: [1, 0, 0, 1, 0, 0] };
	const [sx, sy] = t.scale || [1, 1], [ox, oy] = t.offset || [0, 0], r = t.rotation || 0;
	const c = Math.cos(r), s = Math.sin(r);
	return { texCoord, matrix: [c * sx, s * sy, -s * sx, c * sy, ox, oy] };
}

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
	const [ma, mb, mc, md, ox, oy] = matrix;
	const placed = new Float32Array(2 * n);
	for (let i = 0; i < n; i++) {
		const u = raw.getX(i), v = raw.getY(i);  // normalized integers come back as floats
		placed[2 * i] = ma * u + mb * v + ox;
		placed[2 * i + 1] = mc * u + md * v + oy;
	}
	const uv = new BufferAttribute(placed, 2);
	const du = new Float32Array(3 * n), dv = new Float32Array(3 * n), weight = new Float64Array(n);
	const idx = geometry.index;
	const count = idx ? idx.count : n;
	const p = [0, 1, 2].map(() => [0, 0, 0]), t = [0, 1, 2].map(() => [0, 0]);
	for (let f = 0; f + 2 < count; f += 3) {
		const ids = [0, 1, 2].map((k) => (idx ? idx.getX(f + k) : f + k));
		ids.forEach((i, k) => {
			p[k][0] = pos.getX(i); p[k][1] = pos.getY(i); p[k][2] = pos.getZ(i);
			t[k][0] = uv.getX(i); t[k][1] = uv.getY(i);
		});
		const e1 = [0, 1, 2].map((c) => p[1][c] - p[0][c]), e2 = [0, 1, 2].map((c) => p[2][c] - p[0][c]);
		const d1 = [t[1][0] - t[0][0], t[1][1] - t[0][1]], d2 = [t[2][0] - t[0][0], t[2][1] - t[0][1]];
		const det = d1[0] * d2[1] - d2[0] * d1[1];
		if (!(Math.abs(det) > 1e-20)) continue;
		const cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
		const area = Math.hypot(cx, cy, cz);
		for (const i of ids) {
			weight[i] += area;
			for (let c = 0; c < 3; c++) {
				du[3 * i + c] += area * (e1[c] * d2[1] - e2[c] * d1[1]) / det;
				dv[3 * i + c] += area * (e2[c] * d1[0] - e1[c] * d2[0]) / det;
			}
		}
	}
	for (let i = 0; i < n; i++) {
		for (let c = 0; c < 3 && weight[i] > 0; c++) { du[3 * i + c] /= weight[i]; dv[3 * i + c] /= weight[i]; }
	}
	geometry.setAttribute('csmDpdu', new BufferAttribute(du, 3));
	geometry.setAttribute('csmDpdv', new BufferAttribute(dv, 3));
	geometry.setAttribute('csmTangent', a.tangent);
	geometry.setAttribute('csmUv', uv);
	return null;
}
