// csm_frame.js: where the relief of EXT_materials_cone_step_mapping lies on a mesh, for any
// engine (no engine imports): the step map's uv placement and the per-vertex frame inputs
// both plugins' shaders read (csm_geometry.js for three.js, csm_babylon_mesh.js for Babylon.js).

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

// The inverse of a placement's linear part as a column-major mat2: CSM uv offsets back to the
// mesh's uvs (0 for a singular transform).
export function uvInverse(matrix) {
	const [a, b, c, d] = matrix, det = a * d - b * c, k = det ? 1 / det : 0;
	return [d * k, -c * k, -b * k, a * k];
}

// Per-vertex frame inputs of the relief from flat arrays: position (3n numbers), uv (2n, the
// step map's uv set as the mesh holds it), index (3 per triangle, or null: unindexed) and a
// placement matrix (uvPlacement). Returns { uv: Float32Array(2n), the uvs through the
// placement; dpdu, dpdv: Float32Array(3n), position per CSM uv unit, area-weighted over the
// triangles around each vertex (0 where every triangle around is degenerate in uv) }.
export function frameArrays(position, uv, index = null, matrix = [1, 0, 0, 1, 0, 0]) {
	const n = position.length / 3;
	const [ma, mb, mc, md, ox, oy] = matrix;
	const placed = new Float32Array(2 * n);
	for (let i = 0; i < n; i++) {
		const u = uv[2 * i], v = uv[2 * i + 1];
		placed[2 * i] = ma * u + mb * v + ox;
		placed[2 * i + 1] = mc * u + md * v + oy;
	}
	const du = new Float32Array(3 * n), dv = new Float32Array(3 * n), weight = new Float64Array(n);
	const count = index ? index.length : n;
	const ids = [0, 0, 0], e1 = [0, 0, 0], e2 = [0, 0, 0];
	for (let f = 0; f + 2 < count; f += 3) {
		for (let k = 0; k < 3; k++) ids[k] = index ? index[f + k] : f + k;
		const [i0, i1, i2] = ids;
		for (let c = 0; c < 3; c++) {
			e1[c] = position[3 * i1 + c] - position[3 * i0 + c];
			e2[c] = position[3 * i2 + c] - position[3 * i0 + c];
		}
		const d1 = [placed[2 * i1] - placed[2 * i0], placed[2 * i1 + 1] - placed[2 * i0 + 1]];
		const d2 = [placed[2 * i2] - placed[2 * i0], placed[2 * i2 + 1] - placed[2 * i0 + 1]];
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
	return { uv: placed, dpdu: du, dpdv: dv };
}
