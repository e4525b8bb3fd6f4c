// Validates glTF/GLB files with the Khronos glTF validator and prints one JSON report per file
// on stdout (a JSON array), for frond-gltf's tests. Exit code 0 when every file was read (the
// caller decides what counts as a failure), 2 on usage or read errors.
//
// Usage: node validate.mjs FILE.glb [FILE.gltf ...]
// External resources of a .gltf (its .bin) are loaded relative to the file.
import { readFile } from "node:fs/promises";
import path from "node:path";
import validator from "gltf-validator";

const files = process.argv.slice(2);
if (files.length === 0) {
    console.error("usage: node validate.mjs FILE.glb [FILE.gltf ...]");
    process.exit(2);
}

const reports = [];
for (const file of files) {
    let bytes;
    try {
        bytes = await readFile(file);
    } catch (err) {
        console.error(`cannot read ${file}: ${err.message}`);
        process.exit(2);
    }
    const report = await validator.validateBytes(new Uint8Array(bytes), {
        uri: path.basename(file),
        maxIssues: 100,
        externalResourceFunction: (uri) =>
            readFile(path.resolve(path.dirname(file), decodeURIComponent(uri))).then(
                (data) => new Uint8Array(data),
            ),
    });
    report.file = file;
    reports.push(report);
}
console.log(JSON.stringify(reports, null, 1));
