// loaders.js (csm-assets): what csm_babylon.js imports from @babylonjs/loaders' glTF 2.0 loader,
// taken from the UMD build's global BABYLON.GLTF2 (babylon.glTF2FileLoader.min.js).
const G = globalThis.BABYLON && globalThis.BABYLON.GLTF2;
const registry = G && [G, G.Loader, G.Loader && G.Loader.Extensions].find((x) => x && x.registerGLTFExtension);
if (!registry || !G.GLTFLoader) throw new Error('babylon.glTF2FileLoader.min.js (BABYLON.GLTF2) is not loaded');
export const GLTFLoader = G.GLTFLoader;
export const { registerGLTFExtension, unregisterGLTFExtension } = registry;
