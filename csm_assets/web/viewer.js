// viewer.js: the page of `csm-assets view`: the converted scene drawn by three.js with orbit
// controls and the panel (viewer_panel.js: the variant/steps switch, the debug views and the
// material's settings). Renders on demand.
// window.csmViewer is a small API for scripted checks (see tests/test_view_browser.py).

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { CSMExtension, setVariant } from './csm_plugin.js';
import { debugView, makePanel, starting } from './viewer_panel.js';

const $ = (id) => document.getElementById(id);
const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
renderer.setSize(window.innerWidth, window.innerHeight);
$('view').appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x303030);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
sun.position.set(1, 2, 3);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 0.01, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
let fixedCamera = false;
let materials = [];  // the CSM materials, in glTF order
const draw = () => renderer.render(scene, camera);
controls.addEventListener('change', draw);

window.addEventListener('resize', () => {
	renderer.setSize(window.innerWidth, window.innerHeight);
	if (!fixedCamera) {
		camera.aspect = window.innerWidth / window.innerHeight;
		camera.updateProjectionMatrix();
	}
	draw();
});

const panel = makePanel({
	settingsOf: (m) => m.userData.csm,
	setVariant,
	setDebug: (view, on) => {
		for (const m of materials) {
			const u = m.userData.csm.uniforms;
			if (u) { u.csm_enabled.value = on; u.csm_debug.value = view; }
		}
	},
	draw,
});

function fitCamera(root) {
	const box = new THREE.Box3().setFromObject(root);
	const centre = box.getCenter(new THREE.Vector3());
	const size = Math.max(box.getSize(new THREE.Vector3()).length(), 1e-6);
	camera.near = size / 1000;
	camera.far = size * 100;
	camera.position.copy(centre).add(new THREE.Vector3(0.35, 0.45, 1).normalize().multiplyScalar(1.6 * size));
	camera.updateProjectionMatrix();
	controls.target.copy(centre);
	controls.update();
}

// view, proj: 16 numbers each, row-major (numpy's order): the camera of a scripted check.
function setCamera(view, proj) {
	fixedCamera = true;
	controls.enabled = false;
	const v = new THREE.Matrix4().set(...view);
	camera.matrixAutoUpdate = false;
	camera.matrix.copy(v).invert();
	camera.matrixWorldNeedsUpdate = true;
	camera.updateMatrixWorld(true);
	camera.projectionMatrix.set(...proj);
	camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
	draw();
}

// Render a raw debug view (rawUv or rawInfo) into a float target: base64 of the
// Float32 RGBA pixels, rows bottom-up. relief false: as the plain material (polygon uv).
function readRaw(mode, width, height, relief = true) {
	const view = debugView(mode);
	const target = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType, depthBuffer: true });
	const background = scene.background;
	const live = materials.map((m) => m.userData.csm.uniforms).filter(Boolean);
	const before = live.map((u) => [u.csm_debug.value, u.csm_enabled.value]);
	live.forEach((u) => { u.csm_debug.value = view; u.csm_enabled.value = relief; });
	scene.background = null;
	renderer.setClearColor(0x000000, 0);
	renderer.setRenderTarget(target);
	renderer.clear();
	renderer.render(scene, camera);
	const px = new Float32Array(4 * width * height);
	renderer.readRenderTargetPixels(target, 0, 0, width, height, px);
	renderer.setRenderTarget(null);
	target.dispose();
	scene.background = background;
	live.forEach((u, i) => { [u.csm_debug.value, u.csm_enabled.value] = before[i]; });
	draw();
	const bytes = new Uint8Array(px.buffer);
	let text = '';
	for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
	return btoa(text);
}

async function start() {
	const info = await (await fetch('api/scene.json')).json();
	document.title = `csm-assets view: ${info.name}`;
	$('title').textContent = info.name;
	// only this server's files (and the data:/blob: URLs the loader makes); the page's CSP
	// blocks the rest too, this says which
	const manager = new THREE.LoadingManager();
	manager.setURLModifier((url) => {
		const u = new URL(url, location.href);
		if (u.protocol === 'data:' || u.protocol === 'blob:' || u.origin === location.origin) return url;
		console.warn(`csm-assets view: ${url} is not on this server; not loaded`);
		return 'data:,';
	});
	const loader = new GLTFLoader(manager);
	loader.register((parser) => new CSMExtension(parser));
	// converted Draco and meshopt scenes stay compressed: three.js' own decoders, served from here
	loader.setDRACOLoader(new DRACOLoader(manager).setDecoderPath('./web/three/addons/libs/draco/gltf/'));
	loader.setMeshoptDecoder(MeshoptDecoder);
	const gltf = await loader.loadAsync(info.url);
	scene.add(gltf.scene);
	const seen = new Set();
	gltf.scene.traverse((o) => {
		if (!o.isMesh) return;
		for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
			if (m.userData.csm && !seen.has(m)) { seen.add(m); materials.push(m); }
		}
	});
	fitCamera(gltf.scene);
	renderer.compile(scene, camera);
	draw();
	return panel.setMaterials(materials, info.warnings);
}

const ready = starting(start);
window.csmViewer = {
	ready, setCamera, readRaw, draw, ...panel.api,
	// the sun (the directional light) towards world direction x, y, z (from the origin)
	setLight: (x, y, z) => { sun.position.set(x, y, z); sun.updateMatrixWorld(); draw(); },
	// the sun on or off (the hemisphere sky stays)
	showSun: (on) => { sun.visible = !!on; draw(); },
	// self-shadowing on or off (materials whose extension says selfShadow only)
	setSelfShadow: (on) => {
		for (const m of materials) if (m.userData.csm.selfShadow) m.userData.csm.uniforms.selfShadow.value = !!on;
		draw();
	},
	glInfo: () => {
		const gl = renderer.getContext();
		const dbg = gl.getExtension('WEBGL_debug_renderer_info');
		return { webgl2: gl instanceof WebGL2RenderingContext,
			renderer: dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER) };
	},
};
