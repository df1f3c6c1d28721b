// build.mjs: fills packages/<name>/dist/ with the plugin's modules, copied from csm_assets/web/
// (the files `csm-assets view` ships), so the npm package and the viewer draw with the same
// code. Run by each package's prepack (npm pack, npm publish): node ../build.mjs <name>.
import { copyFileSync, mkdirSync, readFileSync, rmSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const web = join(here, '..', 'csm_assets', 'web');
const SHARED = ['csm_settings.js', 'csm_frame.js', 'csm_frag.js', 'csm_check.js', 'csm_schema.js', 'csm_glsl.js',
	'csm_levels.js'];
export const FILES = {
	three: ['csm_plugin.js', 'csm_geometry.js', 'csm_shader.js', ...SHARED],
	babylon: ['csm_babylon.js', 'csm_babylon_shader.js', ...SHARED],
};

const name = process.argv[2];
if (!Object.hasOwn(FILES, name)) {
	console.error(`build.mjs: expected a package name (${Object.keys(FILES).join(', ')}), got ${name}`);
	process.exit(2);
}
const dist = join(here, name, 'dist');
rmSync(dist, { recursive: true, force: true });
mkdirSync(dist, { recursive: true });
for (const file of FILES[name]) copyFileSync(join(web, file), join(dist, file));
// every relative import of the copied modules is copied too (a file missing from FILES fails here)
for (const file of FILES[name]) {
	for (const [, spec] of readFileSync(join(dist, file), 'utf8').matchAll(/^import [^;]*? from '(\.\/[^']+)';/gm)) {
		if (!FILES[name].includes(spec.slice(2))) throw new Error(`build.mjs: ${file} imports ${spec}, not in the ${name} package`);
	}
}
