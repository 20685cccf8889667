// Validates .glb files with the Khronos glTF validator (npm gltf-validator, installed under
// target/npm-gltf by scripts/setup.sh) and prints one JSON line per file:
// {"file", "errors", "warnings", "infos", "messages": [first 20 issues]}.
// Usage: node scripts/gltf_validate.mjs FILE...
import { createRequire } from "node:module";
import { readFileSync } from "node:fs";
import { resolve, dirname } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const prefix = process.env.FOOTSCAN_GLTF_NPM || resolve(here, "../target/npm-gltf");
const require = createRequire(resolve(prefix, "node_modules") + "/");
const validator = require("gltf-validator");

for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    maxIssues: 0,
  });
  const i = report.issues;
  console.log(
    JSON.stringify({
      file,
      errors: i.numErrors,
      warnings: i.numWarnings,
      infos: i.numInfos,
      messages: i.messages.slice(0, 20),
    }),
  );
}
