// Validate glTF files with the Khronos glTF Validator; prints one JSON report per line.
// Usage: node validate_gltf.js NODE_MODULES_DIR FILE...
const fs = require("fs");
const path = require("path");
const validator = require(path.resolve(process.argv[2], "gltf-validator"));

async function validate(file) {
  const asset = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(asset, {
    uri: path.basename(file),
    maxIssues: 50,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data))
        );
      }),
  });
  return {
    file: file,
    errors: report.issues.numErrors,
    warnings: report.issues.numWarnings,
    messages: report.issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer || ""} ${m.message}`),
  };
}

(async () => {
  for (const file of process.argv.slice(3)) {
    try {
      console.log(JSON.stringify(await validate(file)));
    } catch (error) {
      console.log(JSON.stringify({ file: file, errors: 1, warnings: 0, messages: [String(error)] }));
    }
  }
})();
