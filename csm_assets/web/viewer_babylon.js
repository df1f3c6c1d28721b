// viewer_babylon.js: the page of `csm-assets view --engine babylon`: the converted scene drawn by
// Babylon.js (the UMD build in web/babylon/, the global BABYLON) with the project's loader
// extension (csm_babylon.js), orbit controls, the variant/steps switch, the debug views and the
// material's settings. window.csmViewer is the same small API as viewer.js' (the browser tests
// drive both pages alike).

import { DEBUG, VARIANTS, registerCSMExtension, setVariant, settingsOf } from './csm_babylon.js';
import { mapRefusal } from './csm_settings.js';

const B = globalThis.BABYLON;
const $ = (id) => document.getElementById(id);
const canvas = $('view');
const engine = new B.Engine(canvas, false, { preserveDrawingBuffer: true, stencil: false }, false);
const scene = new B.Scene(engine);
scene.useRightHandedSystem = true;  // glTF's axes: no mirroring root node, cameras as numpy's
scene.clearColor = new B.Color4(0x30 / 255, 0x30 / 255, 0x30 / 255, 1);
// viewer.js' lights (three.js: hemisphere 1.2, sun 2.0) in Babylon's units: its PBR diffuse has no
// 1 / pi (three's Lambert BRDF has), so each intensity is three's over pi
const sky = new B.HemisphericLight('sky', new B.Vector3(0, 1, 0), scene);
sky.intensity = 1.2 / Math.PI;
sky.groundColor = new B.Color3(0.25, 0.25, 0.25);
const sun = new B.DirectionalLight('sun', new B.Vector3(-1, -2, -3), scene);
sun.intensity = 2.0 / Math.PI;
const orbit = new B.ArcRotateCamera('orbit', 0.35, 1.1, 3, B.Vector3.Zero(), scene);
orbit.minZ = 0.01;
orbit.attachControl(canvas, true);
const fixed = new B.UniversalCamera('fixed', new B.Vector3(0, 0, 1), scene);
let materials = [];  // the CSM materials, in glTF order
const draw = () => scene.render();  // on demand, as viewer.js: no render loop
orbit.onViewMatrixChangedObservable.add(() => { if (scene.activeCamera === orbit) draw(); });
window.addEventListener('resize', () => { engine.resize(); draw(); });

function status(text, bad = false) {
	$('status').textContent = text;
	$('status').style.color = bad ? '#f66' : '#fc6';
}

function selected() {
	const i = $('material').value;
	return i === 'all' ? materials : [materials[Number(i)]];
}

const refusal = (m, variant) => mapRefusal(m.name, settingsOf(m).quadrant, variant);

function showSettings() {
	const m = selected()[0];
	if (!m) { $('settings').textContent = 'no material carries EXT_materials_cone_step_mapping'; return; }
	const csm = settingsOf(m);
	for (const o of $('variant').options) {
		const why = selected().map((x) => refusal(x, o.value));
		o.disabled = why.every(Boolean);
		o.title = o.disabled ? why[0] : '';
	}
	$('variant').value = csm.variant;
	$('steps').value = csm.steps;
	const extra = csm.fallback ? `\nfallback: ${csm.fallback}` : '';
	$('settings').textContent = `${m.name || '(unnamed)'}\n${JSON.stringify(csm.extension, null, 1)}${extra}`;
}

function debugView(name) {
	if (!Object.hasOwn(DEBUG, name)) throw new Error(`unknown debug view ${name}; known: off,${Object.keys(DEBUG)}`);
	return DEBUG[name];
}

// the uniforms of every material drawn with the relief (bound on the next draw)
const live = () => materials.map((m) => settingsOf(m).uniforms).filter(Boolean);

function setDebug(name) {
	const view = name === 'off' ? DEBUG.lit : debugView(name);
	for (const u of live()) { u.csm_enabled = name !== 'off'; u.csm_debug = view; }
	scene.resetCachedMaterial();
	draw();
}

function fitCamera(meshes) {
	let min = null, max = null;
	for (const m of meshes) {
		if (!m.getTotalVertices || !m.getTotalVertices()) continue;
		const b = m.getBoundingInfo().boundingBox;
		min = min ? B.Vector3.Minimize(min, b.minimumWorld) : b.minimumWorld.clone();
		max = max ? B.Vector3.Maximize(max, b.maximumWorld) : b.maximumWorld.clone();
	}
	if (!min) return;
	const size = Math.max(max.subtract(min).length(), 1e-6);
	orbit.target = min.add(max).scale(0.5);
	orbit.radius = 1.6 * size;
	orbit.minZ = size / 1000;
	orbit.maxZ = size * 100;
}

// view, proj: 16 numbers each, row-major (numpy's order): the camera of a scripted check. The
// fixed camera takes the view's eye, forward and up (Babylon's right-handed look-at makes the
// same matrix) and the projection as given.
function setCamera(view, proj) {
	const col = (a) => [0, 1, 2, 3].flatMap((c) => [0, 1, 2, 3].map((r) => a[4 * r + c]));
	const inv = B.Matrix.FromArray(col(view)).invert();
	const eye = B.Vector3.TransformCoordinates(B.Vector3.Zero(), inv);
	const forward = B.Vector3.TransformNormal(new B.Vector3(0, 0, -1), inv);
	fixed.position = eye;
	fixed.upVector = B.Vector3.TransformNormal(new B.Vector3(0, 1, 0), inv);
	fixed.setTarget(eye.add(forward));
	fixed.freezeProjectionMatrix(B.Matrix.FromArray(col(proj)));
	orbit.detachControl();
	scene.activeCamera = fixed;
	draw();
}

// A raw debug view (rawUv, rawInfo, rawLight, rawShadow) in a float target: base64 of the Float32
// RGBA pixels, rows bottom-up. relief false: as the plain material (polygon uv).
async function readRaw(mode, width, height, relief = true) {
	const view = debugView(mode);
	const rtt = new B.RenderTargetTexture('csm raw', { width, height }, scene, false, true, B.Constants.TEXTURETYPE_FLOAT,
		false, B.Texture.NEAREST_SAMPLINGMODE);
	rtt.renderList = scene.meshes.slice();
	rtt.clearColor = new B.Color4(0, 0, 0, 0);
	const before = live().map((u) => [u.csm_debug, u.csm_enabled]);
	live().forEach((u) => { u.csm_debug = view; u.csm_enabled = relief; });
	scene.resetCachedMaterial();
	let px;
	try {
		rtt.render();
		px = new Float32Array((await rtt.readPixels()).buffer);
	} finally {
		rtt.dispose();
		live().forEach((u, i) => { [u.csm_debug, u.csm_enabled] = before[i]; });
		scene.resetCachedMaterial();
		draw();
	}
	const bytes = new Uint8Array(px.buffer, 0, 16 * width * height);
	let text = '';
	for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
	return btoa(text);
}

async function start() {
	const info = await (await fetch('api/scene.json')).json();
	document.title = `csm-assets view (Babylon.js): ${info.name}`;
	$('title').textContent = info.name;
	for (const v of Object.keys(VARIANTS)) $('variant').add(new Option(v, v));
	// only this server's files (and the data:/blob: URLs the loader makes)
	B.Tools.PreprocessUrl = (url) => {
		const u = new URL(url, location.href);
		if (u.protocol === 'data:' || u.protocol === 'blob:' || u.origin === location.origin) return url;
		console.warn(`csm-assets view: ${url} is not on this server; not loaded`);
		return 'data:,';
	};
	registerCSMExtension();
	const url = new URL(info.url, location.href).href;
	const result = await B.ImportMeshAsync(url, scene);
	materials = scene.materials.filter((m) => settingsOf(m)).sort((a, b) => settingsOf(a).index - settingsOf(b).index);
	$('material').add(new Option('all materials', 'all'));
	materials.forEach((m, i) => $('material').add(new Option(m.name || `material ${i}`, String(i))));
	fitCamera(result.meshes);
	await scene.whenReadyAsync();
	draw();
	showSettings();
	const fallbacks = materials.filter((m) => settingsOf(m).fallback).length;
	status(`${materials.length} CSM material(s)${fallbacks ? `, ${fallbacks} on the PBR fallback` : ''}`);
	return {
		materials: materials.map((m) => { const c = settingsOf(m); return { name: m.name, variant: c.variant, steps: c.steps,
			fallback: c.fallback, extension: c.extension }; }),
		warnings: info.warnings,
	};
}

$('material').addEventListener('change', showSettings);
$('debug').addEventListener('change', () => setDebug($('debug').value));
function switchVariant(list, variant, steps) {
	const switched = [], refused = [];
	for (const m of list) {
		const csm = settingsOf(m);
		if (!csm.uniforms) continue;  // on the PBR fallback: nothing to switch
		const v = variant ?? csm.variant;
		const why = refusal(m, v);
		if (why) { refused.push(why); continue; }
		setVariant(m, v, steps);
		switched.push(m.name);
	}
	draw();
	return { switched, refused };
}

const applyVariant = (variant) => {
	const { refused } = switchVariant(selected(), variant, Number($('steps').value) || 0);
	showSettings();
	if (refused.length) status(`kept their variant: ${refused.join('; ')}`, true);
};
$('variant').addEventListener('change', () => applyVariant($('variant').value));
$('steps').addEventListener('change', () => applyVariant(null));

const ready = start().catch((e) => {
	status(`error: ${e.message || e}`, true);
	return { error: String(e.message || e) };
});
window.csmViewer = {
	ready, setCamera, readRaw, draw, engine: 'babylon',
	setDebug: (name) => { setDebug(name); $('debug').value = name; },
	setVariant: (variant, steps = 0) => {
		if (!Object.hasOwn(VARIANTS, variant)) throw new Error(`unknown variant ${variant}; known: ${Object.keys(VARIANTS)}`);
		return switchVariant(materials, variant, steps);
	},
	materials: () => materials,
	// the sun (the directional light) towards world direction x, y, z (from the origin)
	setLight: (x, y, z) => { sun.direction = new B.Vector3(-x, -y, -z); draw(); },
	setSelfShadow: (on) => {
		for (const m of materials) { const c = settingsOf(m); if (c.selfShadow && c.uniforms) c.uniforms.selfShadow = !!on; }
		scene.resetCachedMaterial();
		draw();
	},
	showPanel: (on) => { $('panel').style.display = on ? '' : 'none'; },
	glInfo: () => {
		const gl = engine._gl;
		const dbg = gl.getExtension('WEBGL_debug_renderer_info');
		return { webgl2: engine.webGLVersion >= 2,
			renderer: dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER) };
	},
};
