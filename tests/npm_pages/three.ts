// tests/test_npm_packages.py type-checks this against the installed package's index.d.ts (tsc, strict).
import { CSMExtension, setVariant, variantsFor, DEBUG, type CSMSettings } from 'csm-assets-three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { Material } from 'three';
const loader = new GLTFLoader();
loader.register((parser) => new CSMExtension(parser));
const d: number = DEBUG.uv;
export function f(m: Material): string[] { setVariant(m, 'exact', 0); const s = m.userData.csm as CSMSettings; return [s.variant, ...variantsFor(m), String(d)]; }
