// Load a .glb with three.js (GLTFLoader), play its first animation with an AnimationMixer and print the
// skinned vertex and bone positions at the requested frames as JSON.
// Usage: node three_check.mjs NODE_MODULES_DIR FILE.glb FPS FRAME[,FRAME...]
import fs from "fs";
import path from "path";
import { pathToFileURL } from "url";

// Node has no DOM: GLTFLoader decodes embedded images with createImageBitmap, stubbed here to read the PNG
// header, so that a textured file loads and its texture's size shows that three.js got the image bytes.
globalThis.self = globalThis;
globalThis.createImageBitmap = async (blob) => {
  const bytes = new Uint8Array(await blob.arrayBuffer());
  const view = new DataView(bytes.buffer);
  const png = bytes[1] === 0x50 && bytes[2] === 0x4e && bytes[3] === 0x47;
  return { width: png ? view.getUint32(16) : 0, height: png ? view.getUint32(20) : 0, png, close() {} };
};

const [modules, file, fpsArg, framesArg] = process.argv.slice(2);
const url = (p) => pathToFileURL(path.join(modules, p)).href;
const THREE = await import(url("three/build/three.module.js"));
const { GLTFLoader } = await import(url("three/examples/jsm/loaders/GLTFLoader.js"));

const buf = fs.readFileSync(file);
const data = buf.buffer.slice(buf.byteOffset, buf.byteOffset + buf.byteLength);
const gltf = await new GLTFLoader().parseAsync(data, "");
let mesh = null;
gltf.scene.traverse((o) => { if (o.isSkinnedMesh) mesh = o; });
const clip = gltf.animations[0];
const mixer = new THREE.AnimationMixer(gltf.scene);
mixer.clipAction(clip).play();
const out = { revision: THREE.REVISION, clip: clip.name, duration: clip.duration, tracks: clip.tracks.length,
              vertices: {}, bones: {}, uv: null, map: null };
const uvAttr = mesh.geometry.attributes.uv;
if (uvAttr) out.uv = Array.from({ length: uvAttr.count }, (_, i) => [uvAttr.getX(i), uvAttr.getY(i)]);
const map = mesh.material.map;
if (map) out.map = { width: map.image.width, height: map.image.height, png: map.image.png, flipY: map.flipY,
                     channel: map.channel };
const v = new THREE.Vector3();
for (const k of framesArg.split(",").map(Number)) {
  mixer.setTime(k / Number(fpsArg));
  gltf.scene.updateMatrixWorld(true);
  mesh.skeleton.update();
  const n = mesh.geometry.attributes.position.count;
  const verts = new Array(n);
  for (let i = 0; i < n; i++) {
    mesh.getVertexPosition(i, v);  // morph targets and skinning applied
    v.applyMatrix4(mesh.matrixWorld);
    verts[i] = [v.x, v.y, v.z];
  }
  out.vertices[k] = verts;
  out.bones[k] = mesh.skeleton.bones.map((b) => new THREE.Vector3().setFromMatrixPosition(b.matrixWorld).toArray());
}
process.stdout.write(JSON.stringify(out));
