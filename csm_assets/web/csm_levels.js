// csm_levels.js: a step map's level chain (the extension's stepMapLevelsTexture and, for a
// quadrant map, stepMap2LevelsTexture; docs/reference/levels.md) cut into the images both plugins
// (csm_plugin.js, csm_babylon.js) upload as the step map texture's mip levels 1..n, with no engine
// imports. The levels image holds levels 1..n side by side in one row (OpenGL's mip sizes, each
// axis max(1, floor(n / 2)) down to 1x1): level 1 at (0, 0), level k at x = the widths of levels
// 1..k-1. Each level is cut out as the browser decoded it, with no premultiplied alpha and no
// colour-space conversion (the channels are data: heights, cones, slopes).

const RAW = Object.freeze({ premultiplyAlpha: 'none', colorSpaceConversion: 'none' });

// [[w, h], ...] of levels 1..n below a width x height level 0 ([] for a 1x1 map).
export function levelSizes(width, height) {
	const out = [];
	let w = width, h = height;
	while (w > 1 || h > 1) {
		w = Math.max(1, Math.floor(w / 2));
		h = Math.max(1, Math.floor(h / 2));
		out.push([w, h]);
	}
	return out;
}

// [width, height] of the levels image of a width x height step map ([0, 0] for a 1x1 map).
export function atlasSize(width, height) {
	const sizes = levelSizes(width, height);
	return sizes.length ? [sizes.reduce((s, [w]) => s + w, 0), sizes[0][1]] : [0, 0];
}

// Levels 1..n (ImageBitmaps) cut from `atlas` (an ImageBitmap or image, decoded without
// premultiplied alpha), the levels image of a width x height step map. An Error naming both
// sizes when the atlas is not the documented size.
export async function cutLevels(atlas, width, height) {
	const [w, h] = atlasSize(width, height);
	if (!w || atlas.width !== w || atlas.height !== h) {
		throw new Error(`the levels image is ${atlas.width}x${atlas.height}, not ${w}x${h} (levels 1..n of a ` +
			`${width}x${height} step map side by side)`);
	}
	let x = 0;
	return Promise.all(levelSizes(width, height).map(([lw, lh]) => {
		const cut = createImageBitmap(atlas, x, 0, lw, lh, RAW);
		x += lw;
		return cut;
	}));
}

// An ImageBitmap of encoded image bytes (a PNG's), decoded as data: no premultiplied alpha, no
// colour-space conversion.
export function decodeRaw(bytes, mimeType) {
	return createImageBitmap(new Blob([bytes], { type: mimeType || 'image/png' }), RAW);
}

// The level chains of a material's step maps: [levels of stepMapTexture, of stepMap2Texture]
// (ImageBitmaps, level 1 first), both [] when the extension names no levels image (what was
// drawn before: level 0 alone). values: csm_check's values; quadrant: two images; sizes:
// [[w, h] of each step map image]; decode(textureInfo): Promise of the image (ImageBitmap) of
// that texture, decoded as data, or null when it did not load. Anything wrong (a levels image
// missing, not loaded, of the wrong size, or a quadrant map's levels for one image only) gives
// [[], []] and one call of warn(why): the step map is then drawn from level 0 alone.
export async function loadLevels(values, quadrant, sizes, decode, warn) {
	const names = quadrant ? ['stepMapLevelsTexture', 'stepMap2LevelsTexture'] : ['stepMapLevelsTexture'];
	const infos = names.map((name) => values[name]);
	if (!infos.some(Boolean)) return [[], []];
	const missing = names.filter((name, i) => !infos[i]);
	if (missing.length) return fallback(warn, `${missing.join(', ')} missing (a quadrant map's two images have levels, or neither)`);
	try {
		const chains = await Promise.all(infos.map(async (info, i) => {
			const atlas = await decode(info);
			if (!atlas) throw new Error(`${names[i]} ${info.index} did not load`);
			try { return await cutLevels(atlas, ...sizes[i]); } catch (e) { throw new Error(`${names[i]}: ${e.message}`); }
		}));
		return [chains[0], chains[1] || []];
	} catch (e) {
		return fallback(warn, e.message);
	}
}

function fallback(warn, why) {
	warn(`${why}; the step map's level 0 alone is drawn`);
	return [[], []];
}
