// The page of tests/test_npm_packages.py for csm-assets-three, installed from its packed tarball
// with its peer dependency: window.draw(url, view, proj) loads the scene with the package's plugin
// and draws its hit uv view (DEBUG.uv) at a camera given as row-major view and projection matrices.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { CSMExtension, DEBUG } from 'csm-assets-three';

const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setSize(window.innerWidth, window.innerHeight);
document.body.appendChild(renderer.domElement);

window.draw = async (url, view, proj) => {
	const scene = new THREE.Scene();
	const loader = new GLTFLoader();
	loader.register((parser) => new CSMExtension(parser));
	const gltf = await loader.loadAsync(url);
	scene.add(gltf.scene);
	const materials = new Set();
	gltf.scene.traverse((o) => { if (o.isMesh && o.material.userData.csm) materials.add(o.material); });
	for (const m of materials) if (m.userData.csm.uniforms) m.userData.csm.uniforms.csm_debug.value = DEBUG.uv;
	const camera = new THREE.PerspectiveCamera();
	camera.matrixAutoUpdate = false;
	camera.matrix.copy(new THREE.Matrix4().set(...view)).invert();
	camera.updateMatrixWorld(true);
	camera.projectionMatrix.set(...proj);
	camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
	renderer.render(scene, camera);
	return [...materials].map((m) => ({ name: m.name, fallback: m.userData.csm.fallback }));
};
window.pageReady = true;
