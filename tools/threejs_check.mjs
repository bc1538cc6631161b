// Client check: our GLB as three.js plays it, against the animation it came from.
//
//     node tools/threejs_check.mjs ref.bin dance.glb          # prints one JSON object
//
// Runs three.js's own GLTFLoader and AnimationMixer in node (no browser: the morphing that matters
// here is three.js's, not the GPU's). three resolves from HRR_NODE_MODULES (default
// .venv/node/node_modules, where `make install` puts it). ref.bin (tests/export/test_threejs.py
// writes it): int32 frames T, vertices V, faces F, float64 fps, then T x V x 3 float32 positions
// and F x 3 uint32 faces, little endian.
//
// For every frame f, the mixer is set to f / fps and the garment's vertices are read back as
// three.js morphs them (Mesh.getVertexPosition: base + weighted morph targets, the same sum its
// shaders make); its normals as its shaders blend them (base normal + weighted morph normals,
// normalised). Reports the largest vertex error (mm), the normals' angle from the reference
// frame's angle-weighted normals (99th percentile and largest, degrees), the clip's duration
// against (T - 1) / fps, and whether every key time falls on a frame.

import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const modules = process.env.HRR_NODE_MODULES || path.resolve(".venv/node/node_modules");
const three = await import(pathToFileURL(path.join(modules, "three/build/three.module.js")).href);
const { GLTFLoader } = await import(pathToFileURL(path.join(modules, "three/examples/jsm/loaders/GLTFLoader.js")).href);

function readReference(file) {
  const buf = fs.readFileSync(file);
  const view = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  const [T, V, F] = [0, 4, 8].map((o) => view.getInt32(o, true));
  const fps = view.getFloat64(12, true);
  const positions = new Float32Array(buf.buffer.slice(buf.byteOffset + 20, buf.byteOffset + 20 + T * V * 12));
  const faceStart = buf.byteOffset + 20 + T * V * 12;
  const faces = new Uint32Array(buf.buffer.slice(faceStart, faceStart + F * 12));
  return { T, V, F, fps, positions, faces };
}

// angle-weighted unit vertex normals of frame f (what Blender and USD renderers compute)
function angleNormals(ref, f) {
  const { V, F, positions, faces } = ref;
  const p = (i, k) => positions[(f * V + i) * 3 + k];
  const out = new Float64Array(V * 3);
  for (let t = 0; t < F; t++) {
    const idx = [faces[3 * t], faces[3 * t + 1], faces[3 * t + 2]];
    const a = [0, 1, 2].map((k) => p(idx[0], k)), b = [0, 1, 2].map((k) => p(idx[1], k)), c = [0, 1, 2].map((k) => p(idx[2], k));
    const n = cross(sub(b, a), sub(c, a));
    const len = Math.hypot(...n);
    if (len < 1e-30) continue;
    const corners = [[a, b, c], [b, c, a], [c, a, b]];
    for (let k = 0; k < 3; k++) {
      const [o, u, w] = corners[k];
      const e1 = sub(u, o), e2 = sub(w, o);
      const angle = Math.atan2(Math.hypot(...cross(e1, e2)), dot(e1, e2));
      for (let j = 0; j < 3; j++) out[idx[k] * 3 + j] += (n[j] / len) * angle;
    }
  }
  return out;
}
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];

async function main() {
  const [refFile, glbFile] = process.argv.slice(2);
  if (!refFile || !glbFile) {
    console.error("usage: node tools/threejs_check.mjs ref.bin file.glb");
    process.exit(2);
  }
  const ref = readReference(refFile);
  const data = fs.readFileSync(glbFile);
  const gltf = await new GLTFLoader().parseAsync(data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength), "");
  let garment = null;
  gltf.scene.traverse((o) => { if (o.isMesh && o.geometry.attributes.position.count === ref.V && !garment) garment = o; });
  if (!garment) throw new Error(`${glbFile}: no mesh with the clip's ${ref.V} vertices`);
  const clip = gltf.animations[0];
  const mixer = new three.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(clip);
  action.setLoop(three.LoopOnce, 1);  // played once and held: the default loop wraps the last frame to the first
  action.clampWhenFinished = true;
  action.play();
  const times = new Set();
  for (const track of clip.tracks) for (const t of track.times) times.add(t);
  const onFrames = [...times].every((t) => Math.abs(t * ref.fps - Math.round(t * ref.fps)) < 1e-3);
  const normal = garment.geometry.attributes.normal, morphNormals = garment.geometry.morphAttributes.normal || [];
  const v = new three.Vector3();
  let worst = 0;
  const angles = [];
  for (let f = 0; f < ref.T; f++) {
    mixer.setTime(f / ref.fps);
    garment.updateMatrixWorld(true);
    const expected = normal ? angleNormals(ref, f) : null;
    const w = garment.morphTargetInfluences || [];
    for (let i = 0; i < ref.V; i++) {
      garment.getVertexPosition(i, v).applyMatrix4(garment.matrixWorld);
      const o = (f * ref.V + i) * 3;
      worst = Math.max(worst, Math.hypot(v.x - ref.positions[o], v.y - ref.positions[o + 1], v.z - ref.positions[o + 2]));
      if (!normal) continue;
      const n = [normal.getX(i), normal.getY(i), normal.getZ(i)];
      for (let k = 0; k < morphNormals.length; k++) {
        if (!w[k]) continue;  // glTF morph targets are relative: base + sum of weighted deltas
        n[0] += w[k] * morphNormals[k].getX(i); n[1] += w[k] * morphNormals[k].getY(i); n[2] += w[k] * morphNormals[k].getZ(i);
      }
      const e = [expected[3 * i], expected[3 * i + 1], expected[3 * i + 2]];
      const c = dot(n, e) / Math.max(Math.hypot(...n) * Math.hypot(...e), 1e-30);
      angles.push((Math.acos(Math.min(1, Math.max(-1, c))) * 180) / Math.PI);
    }
  }
  angles.sort((a, b) => a - b);
  const result = {
    file: glbFile, duration_s: clip.duration, clip_duration_s: (ref.T - 1) / ref.fps, keys_on_frames: onFrames,
    max_vertex_error_mm: 1000 * worst,
    normal_error_p99_deg: angles.length ? angles[Math.floor(0.99 * (angles.length - 1))] : null,
    normal_error_max_deg: angles.length ? angles[angles.length - 1] : null,
  };
  console.log(JSON.stringify(result));
}

main().catch((err) => { console.error(String(err && err.stack || err)); process.exit(1); });
