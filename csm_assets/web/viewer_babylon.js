// viewer_babylon.js: the page of `csm-assets view --engine babylon` (loaded by viewer_entry.js):
// the converted scene drawn by Babylon.js (the UMD build in web/babylon/, the global BABYLON)
// with the project's loader extension (csm_babylon.js), orbit controls and the panel
// (viewer_panel.js). window.csmViewer is the same small API as viewer.js' (the browser tests
// drive both alike). Renders on demand.

import { registerCSMExtension, setVariant, settingsOf } from './csm_babylon.js';
import { debugView, makePanel, starting } from './viewer_panel.js';

const B = globalThis.BABYLON;
const $ = (id) => document.getElementById(id);
const canvas = document.createElement('canvas');
canvas.style.cssText = 'position: absolute; inset: 0; width: 100%; height: 100%; display: block';
$('view').appendChild(canvas);
const engine = new B.Engine(canvas, false, { preserveDrawingBuffer: true, stencil: false }, false);
const scene = new B.Scene(engine);
scene.useRightHandedSystem = true;  // glTF's axes: no mirroring root node, cameras as numpy's
scene.clearColor = new B.Color4(0x30 / 255, 0x30 / 255, 0x30 / 255, 1);
// viewer.js' lights (three.js: hemisphere 1.2 from white down to 0x404040, sun 2.0) in Babylon's
// units, measured in Babylon 9.28: its hemispheric light's diffuse has no 1 / pi (three's
// Lambert BRDF has: the intensity is three's over pi), its directional light's has (the same
// intensity); colours are linear (0x404040 is sRGB in three.js, linear 0.051)
const sky = new B.HemisphericLight('sky', new B.Vector3(0, 1, 0), scene);
sky.intensity = 1.2 / Math.PI;
sky.groundColor = B.Color3.FromHexString('#404040').toLinearSpace();
const sun = new B.DirectionalLight('sun', new B.Vector3(-1, -2, -3), scene);
sun.intensity = 2.0;
const orbit = new B.ArcRotateCamera('orbit', 0.35, 1.1, 3, B.Vector3.Zero(), scene);
orbit.minZ = 0.01;
orbit.attachControl(canvas, true);
const fixed = new B.UniversalCamera('fixed', new B.Vector3(0, 0, 1), scene);
let materials = [];  // the CSM materials, in glTF order
const draw = () => scene.render();  // on demand, as viewer.js: no render loop
orbit.onViewMatrixChangedObservable.add(() => { if (scene.activeCamera === orbit) draw(); });
window.addEventListener('resize', () => { engine.resize(); draw(); });

// the uniforms of every material drawn with the relief (bound on the next draw)
const live = () => materials.map((m) => settingsOf(m).uniforms).filter(Boolean);

const panel = makePanel({
	settingsOf,
	setVariant,
	setDebug: (view, on) => {
		for (const u of live()) { u.csm_enabled = on; u.csm_debug = view; }
		scene.resetCachedMaterial();
	},
	draw,
});

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
	// only this server's files (and the data:/blob: URLs the loader makes)
	B.Tools.PreprocessUrl = (url) => {
		const u = new URL(url, location.href);
		if (u.protocol === 'data:' || u.protocol === 'blob:' || u.origin === location.origin) return url;
		console.warn(`csm-assets view: ${url} is not on this server; not loaded`);
		return 'data:,';
	};
	registerCSMExtension();
	// converted Draco and meshopt scenes stay compressed: decoded with the decoders three.js ships
	// (web/three/addons/libs), served from here (absolute URLs: Babylon's Draco workers import them)
	const here = (path) => new URL(path, location.href).href;
	B.DracoDecoder.DefaultConfiguration = { wasmUrl: here('web/three/addons/libs/draco/gltf/draco_wasm_wrapper.js'),
		wasmBinaryUrl: here('web/three/addons/libs/draco/gltf/draco_decoder.wasm'), fallbackUrl: '' };
	B.MeshoptCompression.Configuration = { decoder: { url: here('web/babylon_meshopt.js') } };
	const url = new URL(info.url, location.href).href;
	// a lean output names its scene's textures by ../ uris, which Babylon's glTF loader refuses
	// unless it preprocesses each URL itself: resolved here, then fetched from this server alone
	const preprocessUrlAsync = async (u) => new URL(u, location.href).href;
	const result = await B.ImportMeshAsync(url, scene, { pluginOptions: { gltf: { preprocessUrlAsync } } });
	materials = scene.materials.filter((m) => settingsOf(m)).sort((a, b) => settingsOf(a).index - settingsOf(b).index);
	fitCamera(result.meshes);
	await scene.whenReadyAsync();
	draw();
	return panel.setMaterials(materials, info.warnings);
}

const ready = starting(start);
window.csmViewer = {
	ready, setCamera, readRaw, draw, ...panel.api,
	// the sun (the directional light) towards world direction x, y, z (from the origin)
	setLight: (x, y, z) => { sun.direction = new B.Vector3(-x, -y, -z); draw(); },
	// the sun on or off (the hemispheric sky stays; the materials recompile first)
	showSun: async (on) => { sun.setEnabled(!!on); await scene.whenReadyAsync(); draw(); },
	setSelfShadow: (on) => {
		for (const m of materials) { const c = settingsOf(m); if (c.selfShadow && c.uniforms) c.uniforms.selfShadow = !!on; }
		scene.resetCachedMaterial();
		draw();
	},
	glInfo: () => {
		const gl = engine._gl;
		const dbg = gl.getExtension('WEBGL_debug_renderer_info');
		return { webgl2: engine.webGLVersion >= 2,
			renderer: dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER) };
	},
};
