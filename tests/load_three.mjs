// Loads GLB files with three.js's GLTFLoader (a real client), as a web
// viewer would, and checks what an artist sees (issue 16):
//   - the model stands up: its height runs along +Y, matching the Z extent
//     graftal reports in the stats (glTF is +Y up; graftal's kernel Z-up);
//   - one node per part, named as the stats' `parts` list, in order;
//   - every mesh has a PBR material (MeshStandardMaterial);
//   - vertex counts: every kernel vertex is loaded (shared vertices may be
//     split by normals, never lost).
//
// Usage (three installed anywhere, NODE_PATH pointing at its node_modules):
//   NODE_PATH=DIR/node_modules node tests/load_three.mjs out/examples/a.glb ...
// Each FILE.glb needs its stats beside it as FILE.json (`graftal run ... --stats`).
// Exit status: 0 all good, 1 a check failed, 2 usage or setup errors.

import { createRequire } from 'node:module';
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node tests/load_three.mjs FILE.glb...');
  process.exit(2);
}

// Resolve `three` from NODE_PATH (ES modules ignore NODE_PATH themselves).
const require = createRequire(path.join(process.cwd(), 'noop.js'));
let THREE, GLTFLoader;
try {
  // `three` resolves to build/three.cjs; its package root is two levels up.
  const root = path.dirname(path.dirname(require.resolve('three')));
  THREE = await import(pathToFileURL(path.join(root, 'build/three.module.js')).href);
  ({ GLTFLoader } = await import(
    pathToFileURL(path.join(root, 'examples/jsm/loaders/GLTFLoader.js')).href
  ));
} catch (e) {
  console.error(`cannot load three: npm install --prefix DIR three@0.170.0 and set NODE_PATH=DIR/node_modules (${e.message})`);
  process.exit(2);
}

let failed = 0;
for (const file of files) {
  const problems = [];
  const bytes = await readFile(file);
  const stats = JSON.parse(await readFile(file.replace(/\.glb$/, '.json'), 'utf8'));
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const gltf = await new Promise((resolve, reject) =>
    new GLTFLoader().parse(buffer, '', resolve, reject),
  );
  const scene = gltf.scene;
  scene.updateMatrixWorld(true);

  // Up axis: three's box height (Y) is graftal's Z extent.
  const box = new THREE.Box3().setFromObject(scene);
  const [lo, hi] = stats.mesh.bounds;
  const zExtent = hi[2] - lo[2];
  const yExtent = box.max.y - box.min.y;
  if (Math.abs(yExtent - zExtent) > 1e-4 * Math.max(1, zExtent)) {
    problems.push(`height along +Y is ${yExtent}, graftal's Z extent is ${zExtent}`);
  }
  // glTF's +Y up turns graftal's y into -z: the model's front (-y) faces +z.
  const yGraftal = hi[1] - lo[1];
  if (Math.abs((box.max.z - box.min.z) - yGraftal) > 1e-4 * Math.max(1, yGraftal)) {
    problems.push(`depth along Z is ${box.max.z - box.min.z}, graftal's Y extent is ${yGraftal}`);
  }

  // Parts: one top-level node per part, in order.
  const names = scene.children.map((c) => c.name);
  const parts = stats.parts.map((p) => p.name);
  if (JSON.stringify(names) !== JSON.stringify(parts)) {
    problems.push(`nodes ${JSON.stringify(names)}, parts ${JSON.stringify(parts)}`);
  }

  // Materials and vertex counts.
  let vertices = 0;
  let surfaces = 0;
  scene.traverse((o) => {
    if (o.isMesh) {
      surfaces += 1;
      if (!o.material || !o.material.isMeshStandardMaterial) {
        problems.push(`mesh ${o.name} has no PBR material`);
      }
    }
    if (o.isMesh || o.isLineSegments) {
      vertices += o.geometry.attributes.position.count;
    }
  });
  if (stats.mesh.faces > 0 && surfaces === 0) {
    problems.push('no surface mesh loaded');
  }
  if (vertices < stats.mesh.vertices) {
    problems.push(`${vertices} vertices loaded, the model has ${stats.mesh.vertices}`);
  }
  if (problems.length > 0) {
    failed += 1;
    console.log(`${file}: FAILED\n  ${problems.join('\n  ')}`);
  } else {
    console.log(`${file}: three.js loads ${names.length} part(s), ${vertices} vertices, height ${yExtent.toFixed(4)} along +Y`);
  }
}
process.exit(failed > 0 ? 1 : 0);
