// viewer_entry.js: the page's first module. The engine that draws (api/scene.json's `engine`,
// what `csm-assets view --engine` says) picks the viewer: viewer.js (three.js), or
// viewer_babylon.js once the shipped Babylon.js build (web/babylon/: the global BABYLON, which
// the import map's @babylonjs shims read) has loaded. window.csmViewer.ready waits for the
// viewer's own ready; a page that cannot start says why in the status line and in { error }.

import { starting } from './viewer_panel.js';

const BABYLON_BUILD = ['./web/babylon/babylon.js', './web/babylon/babylon.glTF2FileLoader.min.js'];

function script(src) {
	return new Promise((resolve, reject) => {
		const s = document.createElement('script');
		s.src = src;
		s.onload = resolve;
		s.onerror = () => reject(new Error(`${src} did not load`));
		document.head.appendChild(s);
	});
}

window.csmViewer = {
	ready: starting(async () => {
		const { engine } = await (await fetch('api/scene.json')).json();
		if (engine === 'babylon') {
			for (const src of BABYLON_BUILD) await script(src);
			await import('./viewer_babylon.js');
		} else {
			await import('./viewer.js');
		}
		return window.csmViewer.ready;
	}),
};
