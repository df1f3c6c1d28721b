// core.js (csm-assets): what csm_babylon.js imports from @babylonjs/core, taken from the UMD
// build's global BABYLON (babylon.js, loaded by the page before any module).
const B = globalThis.BABYLON;
if (!B || !B.MaterialPluginBase) throw new Error('babylon.js (the global BABYLON) is not loaded');
export const { MaterialPluginBase, PBRMaterial, Texture } = B;
export default B;
