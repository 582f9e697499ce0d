// anima viewer: the animated avatar (three.js), the videos and the speech in sync on one timeline, curves of
// ARKit weights and wrist speeds, and the evidence marks of each kind of result. Bundled by esbuild at set-up
// (./dev setup) into anima/view/static/viewer.js; it reads window.ANIMA_VIEW and window.ANIMA_GLB (script files
// written by `anima view`), so it needs no network and also works opened from disk.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { VRMLoaderPlugin } from "@pixiv/three-vrm";
import { VRMAnimationLoaderPlugin, createVRMAnimationClip } from "@pixiv/three-vrm-animation";

const V = window.ANIMA_VIEW;
const t0 = performance.now();
const $ = (id) => document.getElementById(id);
const api = { ready: false, frame: 0, playing: false, readyMs: null, rendered: 0, renderedFrames: 0 };
window.anima = api;

function b64ToBuffer(s) {
  const bin = atob(s);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out.buffer;
}

if (V.no3d) document.body.classList.add("no3d");
// ---- page text ----------------------------------------------------------------------------------------
document.title = `anima: ${V.title}`;
$("title").textContent = V.title;
if (V.prompt) $("prompt").textContent = `prompt: “${V.prompt}”`;
for (const n of V.notes || []) {
  const p = document.createElement("div");
  p.className = "note";
  p.textContent = n;
  $("notes").appendChild(p);
}
const summary = V.summary || {};
$("summary").textContent = Object.entries(summary)
  .slice(0, 12)
  .map(([k, v]) => `${k}: ${v}`)
  .join("  ·  ");

// ---- media ------------------------------------------------------------------------------------------------
const videos = [];
for (const v of V.videos || []) {
  const box = document.createElement("figure");
  const el = document.createElement("video");
  el.src = `./${encodeURIComponent(v.file)}`;
  el.muted = true;
  el.preload = "auto";
  el.playsInline = true;
  el.dataset.role = v.role;
  const cap = document.createElement("figcaption");
  cap.textContent = v.role;
  box.appendChild(el);
  box.appendChild(cap);
  $("videos").appendChild(box);
  videos.push(el);
}
let audio = null;
if (V.audio) {
  audio = new Audio(V.audio);
  audio.preload = "auto";
}
const fps = V.fps;
let frames = V.frames;

// ---- 3D ---------------------------------------------------------------------------------------------------
const canvas = $("view3d");
// the page's switches after its '#', joined by '&': "noface" (no face close-up), "aa" / "noaa" (edges drawn smooth
// or not, whatever the GL)
const HASH = new Set(location.hash.slice(1).split("&").filter(Boolean));
// the browser's WebGL renderer, as the driver names it ("" where it says nothing)
function glName() {
  try {
    const gl = document.createElement("canvas").getContext("webgl");
    if (!gl) return "";
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    const lose = gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    return name;
  } catch (e) {
    return "";
  }
}
// Edges drawn smooth (multisampling) on a GPU, where it costs almost nothing: the lids, the lips and the limbs
// without stair steps. A software rasterizer (SwiftShader, llvmpipe: a machine without a GPU) draws without it,
// and the material is Lambert's, so the page still draws the clip's frame rate there.
const GL_NAME = glName();
const SOFTWARE_GL = GL_NAME === "" || /swiftshader|llvmpipe|softpipe|software/i.test(GL_NAME);
const SMOOTH = HASH.has("aa") || (!HASH.has("noaa") && !SOFTWARE_GL);
api.gl = { renderer: GL_NAME, software: SOFTWARE_GL, antialias: SMOOTH };
const renderer = new THREE.WebGLRenderer({ canvas, antialias: SMOOTH });
renderer.setPixelRatio(1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1c1c1c);
const camera = new THREE.PerspectiveCamera(30, 1, 0.01, 100);
scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, 1, 1.5);
scene.add(sun);
const controls = new OrbitControls(camera, canvas);
let mixer = null;
let morphMesh = null;
let bones = {};
let headNode = null;
let skeletonHelper = null;
// the 3D is drawn when something in it changed (a frame, the camera, the page's size), not on every
// animation frame: a 25 fps clip on a 60 Hz screen would draw each frame 2.4 times, and without a GPU
// (SwiftShader) those draws take the time the frames need
let dirty = true;
const redraw = () => (dirty = true);
controls.addEventListener("change", redraw);
$("skeleton").onchange = () => {
  if (skeletonHelper) skeletonHelper.visible = $("skeleton").checked;
  redraw();
};
let clipIndex = 0;

function resize() {
  dirty = true;
  sizeFace();
  const w = canvas.clientWidth;
  const h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);

// Aim the camera at what is drawn at the current frame: the bones (a body in its first pose, not its T-pose)
// and the head's vertices.
function frameView() {
  scene.updateMatrixWorld(true);
  const box = new THREE.Box3();
  for (const b of Object.values(bones)) box.expandByPoint(b.getWorldPosition(new THREE.Vector3()));
  if (morphMesh) box.union(new THREE.Box3().setFromObject(morphMesh, true));
  if (box.isEmpty()) return;
  const c = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3());
  const fov = (camera.fov * Math.PI) / 180;
  const dist = (0.5 * Math.max(size.y, size.x / camera.aspect)) / Math.tan(fov / 2) + size.z;
  controls.target.copy(c);
  camera.position.copy(avatarFront()).multiplyScalar(dist * 1.15).add(c); // in front of the character
  camera.near = dist / 100;
  camera.far = dist * 100;
  camera.updateProjectionMatrix();
  controls.update();
}

// the way a user's avatar faces at its rest, as anima measured it (its hips' and shoulders' left-right line);
// anima's character and a glTF without that faces +Z
function avatarFront() {
  const f = V.avatar && V.avatar.front;
  return f && f.length === 3 ? new THREE.Vector3(f[0], f[1], f[2]).normalize() : new THREE.Vector3(0, 0, 1);
}

// a user's VRM (`anima view --avatar x.vrm`): three-vrm loads it, the result comes as a VRM Animation
let vrm = null;
let vrmUpdate = false; // a VRM Animation drives the normalized bones and the expressions: vrm.update() applies them
function parseGltf(b64, plugin) {
  const loader = new GLTFLoader();
  if (plugin) loader.register(plugin);
  return new Promise((resolve, reject) => loader.parse(b64ToBuffer(b64), "", resolve, reject));
}
// the avatar's objects by glTF node index: `anima live --avatar` sends each frame as node rotations and weights
const nodeByIndex = [];
function indexNodes(gltf) {
  gltf.scene.traverse((o) => {
    const a = gltf.parser.associations.get(o);
    if (a && a.nodes !== undefined && !nodeByIndex[a.nodes]) nodeByIndex[a.nodes] = o;
  });
}
async function loadVrm() {
  const gltf = await parseGltf(window.ANIMA_GLB, (p) => new VRMLoaderPlugin(p));
  vrm = gltf.userData.vrm;
  if (!vrm) throw new Error("the avatar is not a VRM 1.0 three-vrm can read");
  indexNodes(gltf);
  let clip;
  if (V.live) {
    // posed by the stream, frame by frame, on the avatar's own bones (anima.export.retarget.LiveRetarget)
    vrm.humanoid.autoUpdateHumanBones = false;
  } else if (window.ANIMA_VRMA) {
    const anim = await parseGltf(window.ANIMA_VRMA, (p) => new VRMAnimationLoaderPlugin(p));
    clip = createVRMAnimationClip(anim.userData.vrmAnimations[0], vrm);
    vrmUpdate = true;
  } else {
    // retargeted by anima onto the avatar's own rest: the animation moves its bones and morphs directly
    vrm.humanoid.autoUpdateHumanBones = false;
    clip = gltf.animations[0];
  }
  scene.add(vrm.scene);
  vrm.scene.traverse((o) => {
    if (o.isMesh) o.frustumCulled = false;
    if (o.isBone) bones[o.name] = o;
  });
  if (clip) {
    mixer = new THREE.AnimationMixer(vrm.scene);
    mixer.clipAction(clip).play();
  }
  resize();
}

function load3d() {
  if (window.ANIMA_GLB && !V.no3d && V.avatar && V.avatar.vrm) return loadVrm();
  return new Promise((resolve, reject) => {
    if (!window.ANIMA_GLB || V.no3d) {
      $("view3d").style.display = "none";
      resolve();
      return;
    }
    new GLTFLoader().parse(
      b64ToBuffer(window.ANIMA_GLB),
      "",
      (gltf) => {
        const root = gltf.scene;
        scene.add(root);
        if (V.avatar) indexNodes(gltf);
        const own = !V.avatar; // a user's avatar keeps its materials and draws its morphs on the GPU
        root.traverse((o) => {
          if (o.isMesh) {
            // anima's character: its face's colours (eyes, brows, lips) are the vertices' (COLOR_0)
            if (own) o.material = o.geometry.attributes.color
              ? new THREE.MeshLambertMaterial({ color: 0xffffff, vertexColors: true })
              : new THREE.MeshLambertMaterial({ color: 0xd9d2cc });
            o.frustumCulled = false;
            if (o.morphTargetDictionary && (own || !morphMesh)) {
              morphMesh = o;
              if (own) setupCpuMorph(o);
              if (own && o.isSkinnedMesh) setupFaceMesh(o);
            }
          }
          if (o.isBone) bones[o.name] = o;
        });
        headNode = morphMesh && !Object.keys(bones).length ? root.getObjectByName("face") || morphMesh : null;
        if (Object.keys(bones).length) {
          // the skeleton: an optional overlay (the "skeleton" box), drawn with depth so the body hides it
          skeletonHelper = new THREE.SkeletonHelper(root);
          skeletonHelper.material.depthTest = true;
          skeletonHelper.material.depthWrite = false;
          skeletonHelper.visible = $("skeleton").checked;
          scene.add(skeletonHelper);
          $("skeletonBox").style.display = "inline";
        }
        if (gltf.animations.length && !V.live) {
          mixer = new THREE.AnimationMixer(root);
          const action = mixer.clipAction(gltf.animations[0]);
          action.play();
        }
        resize();
        resolve();
      },
      reject,
    );
  });
}

// ---- face morphs on the CPU ---------------------------------------------------------------------------------
// The head has 52 morph targets (ARKit's) over 11k vertices: blending them in the vertex shader costs 40 ms a
// frame on a software GL (SwiftShader, no GPU). Each target moves few vertices, so the page keeps them sparse and
// blends them here (a few ms), only when the weights change; three.js then draws a plain (skinned) mesh.
let cpuMorph = null;
function setupCpuMorph(mesh) {
  const g = mesh.geometry;
  const targets = g.morphAttributes.position || [];
  const relative = g.morphTargetsRelative;
  const base = g.attributes.position.array;
  const sparse = targets.map((a) => {
    const d = a.array;
    const idx = [];
    const val = [];
    for (let i = 0; i < d.length; i += 3) {
      const dx = relative ? d[i] : d[i] - base[i];
      const dy = relative ? d[i + 1] : d[i + 1] - base[i + 1];
      const dz = relative ? d[i + 2] : d[i + 2] - base[i + 2];
      if (dx !== 0 || dy !== 0 || dz !== 0) {
        idx.push(i);
        val.push(dx, dy, dz);
      }
    }
    return { idx: Int32Array.from(idx), val: Float32Array.from(val) };
  });
  // what a change of weights touches: the vertices the morphs move (moved), the triangles around them, the
  // vertices whose normals those change (renormal) and every triangle at those (rest): only they are redone
  // each frame (the body's other 10k vertices keep their rest positions and normals)
  const moved = new Uint8Array(base.length / 3);
  for (const { idx } of sparse) for (let j = 0; j < idx.length; j++) moved[idx[j] / 3] = 1;
  const index = g.index ? g.index.array : null;
  const T = index ? index.length / 3 : base.length / 9;
  const tri = (t, k) => (index ? index[3 * t + k] : 3 * t + k);
  const renormal = new Uint8Array(moved.length);
  for (let t = 0; t < T; t++) {
    if (moved[tri(t, 0)] || moved[tri(t, 1)] || moved[tri(t, 2)]) {
      for (let k = 0; k < 3; k++) renormal[tri(t, k)] = 1;
    }
  }
  const tris = [];
  for (let t = 0; t < T; t++) {
    if (renormal[tri(t, 0)] || renormal[tri(t, 1)] || renormal[tri(t, 2)]) tris.push(tri(t, 0), tri(t, 1), tri(t, 2));
  }
  const verts = [];
  for (let v = 0; v < moved.length; v++) if (renormal[v]) verts.push(v);
  if (!g.attributes.normal) g.computeVertexNormals();
  cpuMorph = {
    base: Float32Array.from(base),
    sparse,
    last: null,
    moved: Int32Array.from(verts.filter((v) => moved[v])),
    renormal: Int32Array.from(verts),
    tris: Int32Array.from(tris),
  };
  g.morphAttributes = {}; // the dictionary and the influences stay: the animation drives them, we draw them
}
// the normals of the vertices a morph can change, as three.js's computeVertexNormals makes them (the sum of
// the area-weighted normals of the triangles at a vertex, normalised)
function renormal(g) {
  const pos = g.attributes.position.array;
  const nrm = g.attributes.normal.array;
  const { renormal: verts, tris } = cpuMorph;
  for (let j = 0; j < verts.length; j++) {
    const v = 3 * verts[j];
    nrm[v] = nrm[v + 1] = nrm[v + 2] = 0;
  }
  for (let j = 0; j < tris.length; j += 3) {
    const a = 3 * tris[j];
    const b = 3 * tris[j + 1];
    const c = 3 * tris[j + 2];
    const e1x = pos[c] - pos[b];
    const e1y = pos[c + 1] - pos[b + 1];
    const e1z = pos[c + 2] - pos[b + 2];
    const e2x = pos[a] - pos[b];
    const e2y = pos[a + 1] - pos[b + 1];
    const e2z = pos[a + 2] - pos[b + 2];
    const nx = e1y * e2z - e1z * e2y;
    const ny = e1z * e2x - e1x * e2z;
    const nz = e1x * e2y - e1y * e2x;
    for (const v of [a, b, c]) {
      nrm[v] += nx;
      nrm[v + 1] += ny;
      nrm[v + 2] += nz;
    }
  }
  for (let j = 0; j < verts.length; j++) {
    const v = 3 * verts[j];
    const l = Math.hypot(nrm[v], nrm[v + 1], nrm[v + 2]) || 1;
    nrm[v] /= l;
    nrm[v + 1] /= l;
    nrm[v + 2] /= l;
  }
  g.attributes.normal.needsUpdate = true;
}
function updateMorph() {
  if (!cpuMorph || !morphMesh) return;
  const w = morphMesh.morphTargetInfluences;
  const key = w.join(",");
  if (key === cpuMorph.last) return;
  cpuMorph.last = key;
  const g = morphMesh.geometry;
  const pos = g.attributes.position.array;
  const base = cpuMorph.base;
  for (let j = 0; j < cpuMorph.moved.length; j++) {
    const i = 3 * cpuMorph.moved[j];
    pos[i] = base[i];
    pos[i + 1] = base[i + 1];
    pos[i + 2] = base[i + 2];
  }
  for (let k = 0; k < cpuMorph.sparse.length; k++) {
    const wk = w[k];
    if (!wk) continue;
    const { idx, val } = cpuMorph.sparse[k];
    for (let j = 0; j < idx.length; j++) {
      const i = idx[j];
      pos[i] += wk * val[3 * j];
      pos[i + 1] += wk * val[3 * j + 1];
      pos[i + 2] += wk * val[3 * j + 2];
    }
  }
  g.attributes.position.needsUpdate = true;
  renormal(g);
  if (faceMesh) copyToFace(g);
}

// ---- dataset clips ----------------------------------------------------------------------------------------
let clipWeights = null;
let clipRot = null;
function f32(b64) {
  return new Float32Array(b64ToBuffer(b64));
}
function selectClip(i) {
  clipIndex = i;
  const c = V.clips[i];
  clipWeights = f32(c.weights);
  clipRot = f32(c.rotation);
  frames = c.frames;
  $("prompt").textContent = c.texts[0];
  $("events").textContent = c.events.map((e) => `${e[0]} ${e[1]}–${e[2]} s`).join(", ") || "no attribute events";
  for (const li of $("clips").children) li.classList.toggle("active", Number(li.dataset.i) === i);
  setupTimeline();
  seek(0);
}
function listClips() {
  $("videos").appendChild($("clips")); // the clips take the videos' column
  $("clips").style.display = "block";
  V.clips.forEach((c, i) => {
    const li = document.createElement("li");
    li.dataset.i = i;
    // every text from the data as text nodes, never markup (a file may be named `<img onerror=...>.mp4`)
    const b = document.createElement("b");
    b.textContent = String(c.source);
    const split = document.createElement("span");
    split.className = "split";
    split.textContent = String(c.split);
    li.append(b, ` ${Number(c.start_s).toFixed(1)} s `, split, document.createElement("br"), String(c.texts[0] ?? ""));
    li.onclick = () => selectClip(i);
    $("clips").appendChild(li);
  });
}

// ---- timeline ---------------------------------------------------------------------------------------------
const slider = $("slider");
function setupTimeline() {
  slider.max = frames - 1;
  const marks = $("marks");
  marks.replaceChildren();
  for (const r of V.ranges || []) {
    const d = document.createElement("div");
    d.className = "range";
    d.style.left = `${(100 * r.start) / frames}%`;
    d.style.width = `${(100 * (r.end - r.start)) / frames}%`;
    d.title = r.label;
    marks.appendChild(d);
  }
  for (const m of V.marks || []) {
    const d = document.createElement("div");
    d.className = `mark ${m.kind}`;
    d.style.left = `${(100 * m.frame) / frames}%`;
    d.title = `${m.label} (frame ${m.frame})`;
    marks.appendChild(d);
  }
}
slider.oninput = () => {
  pause();
  seek(Number(slider.value));
};
$("play").onclick = () => (api.playing ? pause() : play());
$("prev").onclick = () => {
  pause();
  seek(Math.max(0, api.frame - 1));
};
$("next").onclick = () => {
  pause();
  seek(Math.min(frames - 1, api.frame + 1));
};
window.addEventListener("keydown", (e) => {
  if (e.key === " ") {
    e.preventDefault();
    api.playing ? pause() : play();
  } else if (e.key === "ArrowRight") $("next").onclick();
  else if (e.key === "ArrowLeft") $("prev").onclick();
});

// ---- curves -----------------------------------------------------------------------------------------------
const curveNames = Object.keys(V.curves || {});
const colors = ["#f4a261", "#2a9d8f", "#e9c46a", "#e76f51", "#8ab17d", "#a8dadc", "#c77dff", "#ffafcc", "#90be6d"];
let curveCache = null; // the curves drawn once (per size); each frame adds the cursor and the legend
function drawCurves() {
  const c = $("curves");
  if (!curveNames.length) {
    c.style.display = "none";
    return;
  }
  const w = c.clientWidth;
  const h = c.clientHeight;
  if (!curveCache || curveCache.width !== w || curveCache.height !== h) {
    curveCache = document.createElement("canvas");
    curveCache.width = w;
    curveCache.height = h;
    const g = curveCache.getContext("2d");
    g.fillStyle = "#111";
    g.fillRect(0, 0, w, h);
    curveNames.forEach((n, k) => {
      const ys = V.curves[n];
      let hi = 1e-6;
      for (const y of ys) if (y !== null && y > hi) hi = y;
      g.strokeStyle = colors[k % colors.length];
      g.beginPath();
      let pen = false;
      ys.forEach((y, i) => {
        if (y === null) {
          pen = false;
          return;
        }
        const x = (i / Math.max(1, ys.length - 1)) * w;
        const yy = h - 4 - (y / hi) * (h - 8);
        pen ? g.lineTo(x, yy) : g.moveTo(x, yy);
        pen = true;
      });
      g.stroke();
    });
  }
  if (c.width !== w) c.width = w;
  if (c.height !== h) c.height = h;
  const g = c.getContext("2d");
  g.drawImage(curveCache, 0, 0);
  const x = (api.frame / Math.max(1, frames - 1)) * w;
  g.strokeStyle = "#fff";
  g.beginPath();
  g.moveTo(x, 0);
  g.lineTo(x, h);
  g.stroke();
  $("legend").replaceChildren(
    ...curveNames.map((n, k) => {
      const ys = V.curves[n];
      const v = ys[Math.min(api.frame, ys.length - 1)];
      const span = document.createElement("span");
      span.style.color = colors[k % colors.length];
      span.textContent = `${n} ${v === null ? "–" : Number(v).toFixed(3)}`;
      return span;
    }),
  );
}

// ---- playback -----------------------------------------------------------------------------------------------
let clockStart = 0;
let clockFrom = 0;
// One clock: the first video's when there is one (the 3D view then shows the frame that video shows), else the
// speech's, else the wall clock. The other media follow it and are only re-seeked when they drift by more than
// a frame (video) or 80 ms (audio): seeking on every frame would stall a software-decoding browser.
function masterTime() {
  if (!api.playing) return api.frame / fps;
  if (videos.length && !videos[0].paused) return videos[0].currentTime;
  if (audio && !audio.paused) return audio.currentTime;
  return clockFrom + (performance.now() - clockStart) / 1000;
}
function apply(f) {
  api.frame = f;
  dirty = true;
  if (V.kind === "dataset" && clipWeights && morphMesh) {
    const n = morphMesh.morphTargetInfluences.length;
    for (let k = 0; k < n; k++) morphMesh.morphTargetInfluences[k] = clipWeights[f * n + k];
    const r = new THREE.Vector3(clipRot[f * 3], clipRot[f * 3 + 1], clipRot[f * 3 + 2]);
    const a = r.length();
    morphMesh.parent.quaternion.setFromAxisAngle(a > 1e-9 ? r.normalize() : new THREE.Vector3(1, 0, 0), a);
  } else if (mixer) {
    mixer.setTime(f / fps);
    if (vrmUpdate) vrm.update(0); // the normalized bones and the expressions onto the avatar's own
  }
  updateMorph();
  slider.value = f;
  $("frame").textContent = `frame ${f} / ${frames - 1}   ${(f / fps).toFixed(2)} s`;
  drawCurves();
}
function syncMedia(t, force) {
  videos.forEach((v, i) => {
    if (!force && i === 0 && api.playing) return; // the master
    if (force || Math.abs(v.currentTime - t) > 1 / fps) v.currentTime = Math.min(t, (v.duration || t) - 1e-3);
  });
  if (audio && (force || Math.abs(audio.currentTime - t) > 0.08)) audio.currentTime = t;
}
function seek(f) {
  f = Math.max(0, Math.min(frames - 1, Math.round(f)));
  apply(f);
  syncMedia(f / fps + 0.5 / fps, true);
}
function play() {
  if (api.frame >= frames - 1) seek(0);
  api.playing = true;
  clockFrom = api.frame / fps;
  clockStart = performance.now();
  syncMedia(clockFrom, true);
  for (const v of videos) v.play().catch(() => {});
  if (audio) audio.play().catch(() => {});
  $("play").textContent = "||";
}
function pause() {
  api.playing = false;
  for (const v of videos) v.pause();
  if (audio) audio.pause();
  $("play").textContent = "▶";
}
// ---- the face close up: an inset in the canvas's top right, a second camera mounted on the head, in
// front of its face, so expressions can be judged by eye: anima's character, or a user's skinned avatar (VRM, glTF)
const faceCam = new THREE.PerspectiveCamera(30, 1, 0.01, 10);
faceCam.layers.set(1); // it sees the head's own triangles (headPart) and the lights, nothing else
scene.traverse((o) => {
  if (o.isLight) o.layers.enable(1);
});
let faceMesh = null; // anima's character's head (its morphs blended on the CPU: copyToFace)
let faceVerts = null; // the main mesh's vertex index of each of faceMesh's vertices
let faceFrame = null; // where the close-up looks: {head, centre (head's local), restInv, forward, height}
// one of an attribute's vertices, as its own kind of array (interleaved ones as plain floats)
function pickVertices(a, verts) {
  const n = a.itemSize;
  if (a.isInterleavedBufferAttribute) {
    const out = new Float32Array(verts.length * n);
    verts.forEach((v, i) => {
      for (let c = 0; c < n; c++) out[i * n + c] = a.getComponent(v, c);
    });
    return new THREE.BufferAttribute(out, n);
  }
  const out = new a.array.constructor(verts.length * n);
  verts.forEach((v, i) => {
    for (let c = 0; c < n; c++) out[i * n + c] = a.array[v * n + c];
  });
  return new THREE.BufferAttribute(out, n, a.normalized);
}
// the bone that moves each vertex of a skinned mesh most (its index in the mesh's skeleton)
function mainBones(g) {
  const si = g.attributes.skinIndex;
  const sw = g.attributes.skinWeight;
  const out = new Int32Array(si.count);
  for (let v = 0; v < si.count; v++) {
    let best = -1;
    let bw = -1;
    for (let k = 0; k < si.itemSize; k++) {
      const w = sw.getComponent(v, k);
      if (w > bw) [bw, best] = [w, si.getComponent(v, k)];
    }
    out[v] = best;
  }
  return out;
}
// The triangles of skinned mesh `o` whose three vertices are moved most by bones `keep` says are the head's, as a
// second skinned mesh on layer 1 over the same bones, a child of `o`: its own small buffers (and its morph targets
// where the GPU blends them, sharing `o`'s weights), so the close-up costs the head's vertices, not the body's.
// Returns {mesh, verts: o's vertex index of each of its vertices, main: mainBones of o} or null.
function headPart(o, keep, gpuMorphs) {
  const g = o.geometry;
  if (!g.attributes.skinIndex || !g.attributes.skinWeight || !o.skeleton) return null;
  const inHead = o.skeleton.bones.map((b) => keep(b));
  if (!inHead.some(Boolean)) return null;
  const main = mainBones(g);
  const isHead = (v) => main[v] >= 0 && inHead[main[v]];
  const idx = g.index ? g.index.array : Array.from({ length: g.attributes.position.count }, (_, i) => i);
  // a mesh drawn with several materials (MToon's outline: a second pass) keeps its groups
  const ranges = g.groups.length ? g.groups : [{ start: 0, count: idx.length, materialIndex: 0 }];
  const tris = [];
  const groups = [];
  for (const r of ranges) {
    const from = tris.length;
    for (let t = r.start; t + 2 < Math.min(idx.length, r.start + r.count); t += 3) {
      if (isHead(idx[t]) && isHead(idx[t + 1]) && isHead(idx[t + 2])) tris.push(idx[t], idx[t + 1], idx[t + 2]);
    }
    if (tris.length > from) groups.push([from, tris.length - from, r.materialIndex]);
  }
  if (!tris.length) return null;
  const verts = Int32Array.from(new Set(tris)).sort();
  const local = new Map(Array.from(verts, (v, i) => [v, i]));
  const hg = new THREE.BufferGeometry();
  for (const [name, a] of Object.entries(g.attributes)) hg.setAttribute(name, pickVertices(a, verts));
  if (gpuMorphs) {
    for (const [name, list] of Object.entries(g.morphAttributes)) {
      hg.morphAttributes[name] = list.map((a) => pickVertices(a, verts));
    }
    hg.morphTargetsRelative = g.morphTargetsRelative;
  }
  hg.setIndex(tris.map((v) => local.get(v)));
  if (Array.isArray(o.material)) for (const [s, c, m] of groups) hg.addGroup(s, c, m);
  const mesh = new THREE.SkinnedMesh(hg, o.material);
  mesh.bind(o.skeleton, o.bindMatrix);
  if (gpuMorphs && o.morphTargetInfluences) {
    // the same array: whatever sets the avatar's weights (the animation, three-vrm's expressions) sets these
    mesh.morphTargetInfluences = o.morphTargetInfluences;
    mesh.morphTargetDictionary = o.morphTargetDictionary;
  }
  mesh.frustumCulled = false;
  mesh.layers.set(1);
  o.add(mesh);
  return { mesh, verts, main };
}
// anima's character: its head and neck (the vertices the head or the neck move most); the morphed positions and
// normals are copied over from the body's mesh when they change
function setupFaceMesh(o) {
  const bust = ["Head", "Neck", "HeadTop_End", "Spine2", "LeftShoulder", "RightShoulder"];
  const part = headPart(o, (b) => bust.includes(b.name), false);
  if (!part) return;
  faceMesh = part.mesh;
  faceVerts = part.verts;
}
function copyToFace(g) {
  for (const name of ["position", "normal"]) {
    const src = g.attributes[name].array;
    const a = faceMesh.geometry.attributes[name];
    for (let i = 0; i < faceVerts.length; i++) {
      const v = 3 * faceVerts[i];
      a.array[3 * i] = src[v];
      a.array[3 * i + 1] = src[v + 1];
      a.array[3 * i + 2] = src[v + 2];
    }
    a.needsUpdate = true;
  }
}
const FACE_M = 0.3; // the height of face the inset shows for anima's character (metres)
const FACE_INSET = 0.3; // the inset's side, a fraction of the canvas's height
const facePos = new THREE.Vector3();
// the head's bone: a VRM's humanoid says; else by name (three.js drops the ':' of "mixamorig:Head")
function headBone() {
  if (vrm) return vrm.humanoid.getRawBoneNode("head");
  const named = bones.Head || bones.mixamorigHead || bones["mixamorig:Head"] || bones.head;
  return named || Object.values(bones).find((b) => /(^|[^a-z])head$/i.test(b.name)) || null;
}
// A user's avatar, at its rest (before the first frame is applied): the head's part of each of its skinned meshes
// (the vertices moved most by the head bone or a bone under it: jaw, eyes, hair; or by the neck), and the frame
// the close-up looks from: the skull's vertices' centre and height, and the avatar's front at rest, carried by
// the head's turn from its rest.
function setupAvatarFace() {
  const head = headBone();
  if (!head) return;
  const underHead = new Set();
  head.traverse((b) => underHead.add(b));
  const neck = head.parent;
  const chest = neck && neck.parent;
  const keep = (b) => underHead.has(b) || b === neck || (chest && (b === chest || b.parent === chest));
  const skull = new Set([head]);
  if (vrm) for (const n of ["jaw", "leftEye", "rightEye"]) skull.add(vrm.humanoid.getRawBoneNode(n));
  scene.updateMatrixWorld(true);
  const box = new THREE.Box3();
  const all = new THREE.Box3();
  const p = new THREE.Vector3();
  const meshes = [];
  scene.traverse((o) => {
    if (o.isSkinnedMesh && o.layers.isEnabled(0)) meshes.push(o);
  });
  for (const o of meshes) {
    const part = headPart(o, keep, true);
    if (!part) continue;
    const { main } = part;
    for (const v of part.verts) {
      o.localToWorld(o.getVertexPosition(v, p));
      all.expandByPoint(p);
      if (skull.has(o.skeleton.bones[main[v]])) box.expandByPoint(p);
    }
  }
  // rigid parts under the head (glasses, a hat, or the head itself on a low-poly or robot avatar) are seen too,
  // and framed with the skull
  const rigid = new THREE.Box3();
  head.traverse((o) => {
    if (o.isMesh && !o.isSkinnedMesh) {
      o.layers.enable(1);
      rigid.union(new THREE.Box3().setFromObject(o, true));
    }
  });
  all.union(rigid);
  if (all.isEmpty()) return;
  box.union(rigid);
  const face = box.isEmpty() ? all : box;
  const size = face.getSize(new THREE.Vector3());
  faceFrame = {
    head,
    centre: head.worldToLocal(face.getCenter(new THREE.Vector3())),
    restInv: head.getWorldQuaternion(new THREE.Quaternion()).invert(),
    forward: avatarFront(),
    height: Math.min(0.6, Math.max(0.15, 1.25 * size.y)),
  };
}
// the face's centre and how the head has turned (world), or null where there is no head to look at
function faceTarget() {
  if (!faceFrame) return null;
  const { head, centre, restInv, forward, height } = faceFrame;
  const q = head.getWorldQuaternion(new THREE.Quaternion()).multiply(restInv);
  return { centre: head.localToWorld(centre.clone()), q, forward, height };
}
// its own small canvas over the 3D view's top right (a second WebGL context): drawn when the frame or the head
// changed, at most every FACE_EVERY_MS while playing, so the body's view keeps the clip's frame rate on a
// software GL (drawn in the body's canvas, the close-up cost every frame a second pass)
const FACE_EVERY_MS = 80;
let faceCanvas = null;
let faceRenderer = null;
let faceDirty = true;
let faceDrawnAt = -1e9;
function setupFaceView() {
  if (faceRenderer || HASH.has("noface")) return; // (#noface: the page without it)
  if (faceMesh) {
    const head = headBone();
    // anima's head joint is the skull's base, the face about 9 cm above it; the rig's rest faces +Z
    const centre = new THREE.Vector3(0, 0.085, 0.02);
    const forward = new THREE.Vector3(0, 0, 1);
    if (head) faceFrame = { head, centre, restInv: new THREE.Quaternion(), forward, height: FACE_M };
  } else if (V.avatar && (vrm || morphMesh || Object.keys(bones).length)) {
    setupAvatarFace();
  }
  if (!faceFrame) return;
  const wrap = document.createElement("div");
  wrap.style.position = "relative";
  canvas.parentNode.insertBefore(wrap, canvas);
  wrap.appendChild(canvas);
  faceCanvas = document.createElement("canvas");
  faceCanvas.id = "face3d";
  faceCanvas.title = "the face close up";
  Object.assign(faceCanvas.style, { position: "absolute", top: "4px", right: "4px", outline: "1px solid #333" });
  wrap.appendChild(faceCanvas);
  faceRenderer = new THREE.WebGLRenderer({ canvas: faceCanvas, antialias: SMOOTH });
  faceRenderer.setPixelRatio(1);
  sizeFace();
}
function sizeFace() {
  if (!faceRenderer) return;
  const side = Math.max(64, Math.round(FACE_INSET * canvas.clientHeight));
  faceRenderer.setSize(side, side, true);
  faceDirty = true;
}
function renderFace(now) {
  if (!faceRenderer) return;
  if (api.playing && now - faceDrawnAt < FACE_EVERY_MS) return; // (still dirty: drawn on a later tick)
  const t = faceTarget();
  if (!t) return;
  // the camera rides on the head like a helmet camera: the face seen from straight in front on every frame, only
  // the expression moves (the body's view shows where the head turns; export/avatar.py's face_camera says why)
  const dist = (0.5 * t.height) / Math.tan((faceCam.fov * Math.PI) / 360);
  facePos.copy(t.forward).multiplyScalar(dist).applyQuaternion(t.q).add(t.centre);
  faceCam.position.copy(facePos);
  faceCam.up.set(0, 1, 0).applyQuaternion(t.q);
  faceCam.lookAt(t.centre);
  faceCam.updateMatrixWorld(true);
  faceRenderer.render(scene, faceCam);
  faceDirty = false;
  faceDrawnAt = now;
}

let lastFrame = -1;
function tick() {
  if (api.playing) {
    const t = masterTime();
    const f = Math.floor(t * fps + 1e-6);
    if (f >= frames) {
      pause();
      apply(frames - 1);
    } else if (f !== api.frame) {
      apply(f);
      api.chosenAt = performance.now(); // when the clock said this frame (the tests measure sync from here)
      syncMedia(t, false);
    }
  }
  if (dirty) {
    dirty = false;
    renderer.render(scene, camera);
    faceDirty = true;
    api.rendered += 1;
  }
  if (faceDirty) renderFace(performance.now());
  if (api.frame !== lastFrame) {
    api.renderedFrames += 1;
    lastFrame = api.frame;
  }
  requestAnimationFrame(tick);
}

// ---- what the tests read ----------------------------------------------------------------------------------
api.seek = seek;
api.play = play;
api.pause = pause;
api.state = () => {
  const morphs = {};
  if (morphMesh) {
    for (const [name, k] of Object.entries(morphMesh.morphTargetDictionary))
      morphs[name] = morphMesh.morphTargetInfluences[k];
  }
  const joints = {};
  scene.updateMatrixWorld(true);
  for (const [name, b] of Object.entries(bones)) {
    const p = b.getWorldPosition(new THREE.Vector3());
    joints[name] = [p.x, p.y, p.z];
  }
  let humanoid = null;
  let expressions = null;
  if (vrm) {
    humanoid = {};
    for (const name of Object.keys(vrm.humanoid.humanBones)) {
      const node = vrm.humanoid.getRawBoneNode(name);
      if (node) humanoid[name] = node.getWorldPosition(new THREE.Vector3()).toArray();
    }
    expressions = {};
    for (const e of vrm.expressionManager ? vrm.expressionManager.expressions : []) {
      expressions[e.expressionName] = e.weight;
    }
  }
  return {
    frame: api.frame,
    time: api.frame / fps,
    humanoid,
    expressions,
    playing: api.playing,
    morphs,
    joints,
    videoTimes: videos.map((v) => v.currentTime),
    audioTime: audio ? audio.currentTime : null,
    // seconds since the clock chose the frame shown: the videos' times less this are their times at that moment
    frameAge: api.playing && api.chosenAt ? (performance.now() - api.chosenAt) / 1000 : null,
    clip: V.kind === "dataset" ? V.clips[clipIndex].id : null,
  };
};
api.selectClip = (i) => selectClip(i);
api._debug = { scene, renderer, camera, get mesh() { return morphMesh; } };
// where the head is drawn: page pixels of the face mesh's centre (tests look for the head there)
api.headOnScreen = () => {
  if (!morphMesh) return null;
  scene.updateMatrixWorld(true);
  let centre;
  let size;
  const head = bones.Head || bones["mixamorig:Head"] || bones.head;
  if (head) {
    // a character: the head bone's joint is the skull's base; the face is about 9 cm above it, 18 cm wide
    centre = head.localToWorld(new THREE.Vector3(0, 0.09, 0.03));
    size = new THREE.Vector3(0.18, 0.22, 0.2);
  } else {
    const box = new THREE.Box3().setFromObject(morphMesh, true);
    centre = box.getCenter(new THREE.Vector3());
    size = box.getSize(new THREE.Vector3());
  }
  const p = centre.clone().project(camera);
  const r = canvas.getBoundingClientRect();
  const q = centre.clone().add(new THREE.Vector3(size.x / 2, 0, 0)).project(camera);
  return {
    x: r.left + ((p.x + 1) / 2) * r.width,
    y: r.top + ((1 - p.y) / 2) * r.height,
    halfWidth: (Math.abs(q.x - p.x) / 2) * r.width,
    canvas: [r.left, r.top, r.width, r.height],
  };
};

// the face close-up's square on the page (CSS pixels) and the face centre's place in it, or null without one
api.faceOnScreen = () => {
  const t = faceCanvas ? faceTarget() : null;
  if (!t) return null;
  scene.updateMatrixWorld(true);
  const b = faceCanvas.getBoundingClientRect();
  const p = t.centre.clone().project(faceCam);
  return {
    square: [b.left, b.top, b.width, b.height],
    x: b.left + ((p.x + 1) / 2) * b.width,
    y: b.top + ((1 - p.y) / 2) * b.height,
  };
};

// ---- live (`anima live`): each WebSocket message poses the character ---------------------------------------
// message: {i: source frame, t_cap: its capture time (ms since the epoch), q: [65 x [x, y, z, w]] local rotations
// in V.rig order, w: [52] the character's ARKit morph weights in V.expr order}
function connectLive() {
  api.live = api.live || { received: 0, latencies: [], frames: [], connects: 0, faces: 0 };
  const url = `ws://${location.host}${location.pathname.replace(/[^/]*$/, "")}live`;
  const ws = new WebSocket(url);
  ws.onopen = () => (api.live.connects += 1);
  ws.onmessage = (ev) => {
    const m = JSON.parse(ev.data);
    const L = api.live;
    L.received += 1;
    L.latencies.push(Date.now() - m.t_cap);
    L.frames.push([m.i, performance.now()]);
    if (m.face) L.faces += 1;
    if (L.latencies.length > 5000) L.latencies.splice(0, 1000);
    if (L.frames.length > 5000) L.frames.splice(0, 1000);
    if (m.a) {
      // a user's avatar: its own nodes, retargeted by anima
      for (const r of m.a.r) if (nodeByIndex[r[0]]) nodeByIndex[r[0]].quaternion.set(r[1], r[2], r[3], r[4]);
      const hips = nodeByIndex[m.a.h[0]];
      if (hips) hips.position.set(m.a.h[1], m.a.h[2], m.a.h[3]);
      for (const [node, w] of m.a.m) {
        const o = nodeByIndex[node];
        if (!o) continue;
        const meshes = o.isMesh ? [o] : o.children.filter((c) => c.isMesh);
        for (const mesh of meshes) {
          const inf = mesh.morphTargetInfluences;
          if (inf) for (let k = 0; k < Math.min(inf.length, w.length); k++) inf[k] = w[k];
        }
      }
    } else {
      V.rig.forEach((name, j) => {
        const b = bones[name];
        if (b) b.quaternion.set(m.q[j][0], m.q[j][1], m.q[j][2], m.q[j][3]);
      });
    }
    if (morphMesh && !m.a) {
      const d = morphMesh.morphTargetDictionary;
      V.expr.forEach((name, k) => {
        if (name in d) morphMesh.morphTargetInfluences[d[name]] = m.w[k];
      });
      updateMorph();
    }
    api.frame = m.i;
    api.renderedFrames += 1;
    dirty = true;
    const recent = L.frames.slice(-30);
    const rate = recent.length > 1 ? (1000 * (recent.length - 1)) / (recent[recent.length - 1][1] - recent[0][1]) : 0;
    const lat = L.latencies.slice(-30).sort((a, b) => a - b);
    $("frame").textContent = `live: frame ${m.i}  ${rate.toFixed(1)} frames/s  glass to avatar ${Math.round(
      lat[Math.floor(lat.length / 2)],
    )} ms`;
  };
  ws.onclose = () => setTimeout(connectLive, 1000); // the source restarted, or the page lost it: try again
}

load3d()
  .then(() => {
    if (V.live) {
      for (const id of ["slider", "play", "prev", "next"]) $(id).style.display = "none"; // no timeline: a stream
      connectLive();
    }
    setupFaceView();
    resize();
    if (V.kind === "dataset") {
      listClips();
      selectClip(0);
    } else {
      setupTimeline();
      seek(0);
    }
    frameView();
    api.ready = true;
    api.readyMs = performance.now(); // since the page began to load (navigation start)
    api.scriptMs = performance.now() - t0;
    $("status").textContent = `ready in ${api.readyMs.toFixed(0)} ms`;
    requestAnimationFrame(tick);
  })
  .catch((e) => {
    $("status").textContent = `could not load the 3D: ${e}`;
    api.error = String(e);
  });
