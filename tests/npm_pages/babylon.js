// The page of tests/test_npm_packages.py for csm-assets-babylon, installed from its packed
// tarball with its peer dependencies (ES modules of @babylonjs/core and @babylonjs/loaders):
// window.draw(url, view, proj) loads the scene with the package's extension and draws its hit uv
// view (DEBUG.uv) at a camera given as row-major view and projection matrices.
import { Engine, Scene, UniversalCamera, Vector3, Matrix, Color4, ImportMeshAsync } from '@babylonjs/core/index.js';
import '@babylonjs/loaders/glTF/index.js';
import { DEBUG, registerCSMExtension, settingsOf } from 'csm-assets-babylon';

const canvas = document.createElement('canvas');
canvas.style.cssText = 'position: absolute; inset: 0; width: 100%; height: 100%';
document.body.appendChild(canvas);
const engine = new Engine(canvas, false, { preserveDrawingBuffer: true });

window.draw = async (url, view, proj) => {
	const scene = new Scene(engine);
	scene.useRightHandedSystem = true;
	scene.clearColor = new Color4(0, 0, 0, 1);
	registerCSMExtension();
	await ImportMeshAsync(url, scene);
	const materials = scene.materials.filter((m) => settingsOf(m));
	for (const m of materials) if (settingsOf(m).uniforms) settingsOf(m).uniforms.csm_debug = DEBUG.uv;
	const col = (a) => [0, 1, 2, 3].flatMap((c) => [0, 1, 2, 3].map((r) => a[4 * r + c]));
	const inv = Matrix.FromArray(col(view)).invert();
	const eye = Vector3.TransformCoordinates(Vector3.Zero(), inv);
	const camera = new UniversalCamera('fixed', eye, scene);
	camera.upVector = Vector3.TransformNormal(new Vector3(0, 1, 0), inv);
	camera.setTarget(eye.add(Vector3.TransformNormal(new Vector3(0, 0, -1), inv)));
	camera.freezeProjectionMatrix(Matrix.FromArray(col(proj)));
	await scene.whenReadyAsync();
	scene.render();
	return materials.map((m) => ({ name: m.name, fallback: settingsOf(m).fallback }));
};
window.pageReady = true;
