// tests/test_npm_packages.py type-checks this against the installed package's index.d.ts (tsc, strict).
import { registerCSMExtension, settingsOf, setVariant, variantsFor, DEBUG } from 'csm-assets-babylon';
import type { Material } from '@babylonjs/core/Materials/material.js';
const off: () => boolean = registerCSMExtension({ webgl2: true });
export function f(m: Material): string[] { setVariant(m, 'relaxed', 8); return [settingsOf(m)?.fallback ?? '', ...variantsFor(m), String(DEBUG.rawUv), String(off)]; }
