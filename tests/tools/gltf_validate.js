// Validate a glTF/GLB with the Khronos glTF validator (npm gltf-validator); prints its JSON report.
const fs = require('fs'); const path = require('path');
const validator = require('gltf-validator');
const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator.validateBytes(data, {
  uri: file,
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    const p = path.resolve(path.dirname(file), decodeURIComponent(uri));
    fs.readFile(p, (err, d) => err ? reject(err.toString()) : resolve(new Uint8Array(d)));
  })
}).then(r => { console.log(JSON.stringify(r)); }).catch(e => { console.error(e); process.exit(2); });
