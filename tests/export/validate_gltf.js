// Runs the Khronos glTF validator on one .glb and prints its issue summary as JSON.
// usage: node validate_gltf.js <node_modules>/gltf-validator FILE.glb
const fs = require('fs');
const validator = require(require('path').resolve(process.argv[2]));
const bytes = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(bytes, {maxIssues: 50})
    .then((report) => {
      const issues = report.issues;
      console.log(JSON.stringify({
        numErrors: issues.numErrors,
        numWarnings: issues.numWarnings,
        numInfos: issues.numInfos,
        numHints: issues.numHints,
        messages: issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer || ''}: ${m.message}`),
        validatorVersion: report.validatorVersion,
        info: report.info,
      }));
    })
    .catch((error) => {
      console.error(String(error));
      process.exit(2);
    });
