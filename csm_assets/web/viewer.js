// viewer.js: the page of `csm-assets view`: the converted scene with orbit controls, a
// variant/steps switch (offering only the variants that can draw the selected material's step
// map), the debug views and the material's settings. Renders on demand.
// window.csmViewer is a small API for scripted checks (see tests/test_view_browser.py).

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { CSMExtension, DEBUG, VARIANTS, setVariant, variantRefusal } from './csm_plugin.js';

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

function status(text, bad = false) {
	$('status').textContent = text;
	$('status').style.color = bad ? '#f66' : '#fc6';
}

function selected() {
	const i = $('material').value;
	return i === 'all' ? materials : [materials[Number(i)]];
}

function showSettings() {
	const m = selected()[0];
	if (!m) { $('settings').textContent = 'no material carries EXT_materials_cone_step_mapping'; return; }
	const csm = m.userData.csm;
	// only the variants that can draw a selected material's step map (a quadrant map: quadrant
	// alone; a one-image map: all but quadrant); the others are greyed, their title says why
	for (const o of $('variant').options) {
		const why = selected().map((x) => variantRefusal(x, o.value));
		o.disabled = why.every(Boolean);
		o.title = o.disabled ? why[0] : '';
	}
	$('variant').value = csm.variant;
	$('steps').value = csm.steps;
	const extra = csm.fallback ? `\nfallback: ${csm.fallback}` : '';
	$('settings').textContent = `${m.name || '(unnamed)'}\n${JSON.stringify(csm.extension, null, 1)}${extra}`;
}

// A debug view's number; an Error for a name DEBUG has not (never a prototype's property).
function debugView(name) {
	if (!Object.hasOwn(DEBUG, name)) throw new Error(`unknown debug view ${name}; known: off,${Object.keys(DEBUG)}`);
	return DEBUG[name];
}

function setDebug(name) {
	const view = name === 'off' ? DEBUG.lit : debugView(name);
	for (const m of materials) {
		const u = m.userData.csm.uniforms;
		if (!u) continue;
		u.csm_enabled.value = name !== 'off';
		u.csm_debug.value = view;
	}
	draw();
}

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
	for (const v of Object.keys(VARIANTS)) $('variant').add(new Option(v, v));
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
	$('material').add(new Option('all materials', 'all'));
	materials.forEach((m, i) => $('material').add(new Option(m.name || `material ${i}`, String(i))));
	fitCamera(gltf.scene);
	renderer.compile(scene, camera);
	draw();
	showSettings();
	const fallbacks = materials.filter((m) => m.userData.csm.fallback).length;
	status(`${materials.length} CSM material(s)${fallbacks ? `, ${fallbacks} on the PBR fallback` : ''}`);
	return {
		materials: materials.map((m) => ({ name: m.name, variant: m.userData.csm.variant, steps: m.userData.csm.steps,
			fallback: m.userData.csm.fallback, extension: m.userData.csm.extension })),
		warnings: info.warnings,
	};
}

$('material').addEventListener('change', showSettings);
$('debug').addEventListener('change', () => setDebug($('debug').value));
// Switch `list` to `variant` (null: each keeps its own) with `steps`; a material whose step map
// the variant cannot draw keeps its own (refused: why). Unknown variants throw.
function switchVariant(list, variant, steps) {
	const switched = [], refused = [];
	for (const m of list) {
		if (!m.userData.csm.uniforms) continue;  // on the PBR fallback: nothing to switch
		const v = variant ?? m.userData.csm.variant;
		const why = variantRefusal(m, v);
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
	ready, setCamera, readRaw, draw,
	setDebug: (name) => { setDebug(name); $('debug').value = name; },
	// every material the variant can draw (the others keep theirs): { switched: names, refused: whys }
	setVariant: (variant, steps = 0) => {
		if (!Object.hasOwn(VARIANTS, variant)) throw new Error(`unknown variant ${variant}; known: ${Object.keys(VARIANTS)}`);
		return switchVariant(materials, variant, steps);
	},
	materials: () => materials,
	// the sun (the directional light) towards world direction x, y, z (from the origin)
	setLight: (x, y, z) => { sun.position.set(x, y, z); sun.updateMatrixWorld(); draw(); },
	// self-shadowing on or off (materials whose extension says selfShadow only)
	setSelfShadow: (on) => {
		for (const m of materials) if (m.userData.csm.selfShadow) m.userData.csm.uniforms.selfShadow.value = !!on;
		draw();
	},
	showPanel: (on) => { $('panel').style.display = on ? '' : 'none'; },
	glInfo: () => {
		const gl = renderer.getContext();
		const dbg = gl.getExtension('WEBGL_debug_renderer_info');
		return { webgl2: gl instanceof WebGL2RenderingContext,
			renderer: dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER) };
	},
};
