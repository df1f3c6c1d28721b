// babylon_meshopt.js: the classic script Babylon.js' MeshoptCompression loads before its first
// decode (viewer_babylon.js points MeshoptCompression.Configuration.decoder.url here, so nothing
// comes from Babylon's CDN). Babylon then reads the global MeshoptDecoder: three.js' decoder
// (web/three/addons/libs/meshopt_decoder.module.js, the one viewer.js uses), set once imported;
// until then the global holds only its `ready`, which Babylon awaits first.
globalThis.MeshoptDecoder = {
	ready: import('./three/addons/libs/meshopt_decoder.module.js').then(async ({ MeshoptDecoder }) => {
		await MeshoptDecoder.ready;
		globalThis.MeshoptDecoder = MeshoptDecoder;
	}),
};
