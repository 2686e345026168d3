// The web viewer: a tileset exported by `hlod-build export-3dtiles`, drawn
// by 3DTilesRendererJS (three.js) with the same headlight shading as
// hlod-view, orbit and fly navigation, element picking, and a capped tile
// cache.
//
// URL parameters (all optional):
//   tileset=URL    the tileset (default tiles/tileset.json, as scripts/serve-web.sh serves it)
//   error=PX       screen-space error target, in pixels: our ε (default 2)
//   cache=MIB      the tile cache's cap in MiB (default 512)
//   parse=N        tiles parsed at once, and started per frame (default 5, the library's)
//   camera=x,y,z,qx,qy,qz,qw,fov   a pose as in a path file (scene coordinates, y up)
//   ui=0           no panel (screenshots)
//
// Keys: F toggles fly (W/A/S/D/Q/E move, drag looks) and orbit (drag turns,
// wheel zooms); a click names the element under the pointer.
//
// `window.hlod` is the page's interface for scripts and tests: `ready`
// (a promise), `setPose(array)`, `idle()`, `complete()`, `stats()`, `pick(x, y)`.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { TilesRenderer } from '3d-tiles-renderer';
import { GLTFExtensionsPlugin } from '3d-tiles-renderer/plugins';

const params = new URLSearchParams(location.search);
const tilesetUrl = params.get('tileset') || 'tiles/tileset.json';
const errorTarget = Number(params.get('error') || 2);
const cacheMiB = Number(params.get('cache') || 512);
const parseParam = Number(params.get('parse'));
const parseJobs = parseParam >= 1 ? Math.floor(parseParam) : 5;
const panel = document.getElementById('panel');
if (params.get('ui') === '0') panel.classList.add('hidden');

// hlod-view's look: the vertex colour lit by a two-sided headlight, written
// as it is (no colour-space conversion), on the same background.
const headlight = new THREE.ShaderMaterial({
  vertexColors: true,
  side: THREE.DoubleSide,
  vertexShader: `
    varying vec3 vNormal;
    varying vec3 vView;
    varying vec4 vColor;
    void main() {
      vec4 mv = modelViewMatrix * vec4(position, 1.0);
      vNormal = normalMatrix * normal;
      vView = -mv.xyz;
    #ifdef USE_COLOR_ALPHA
      vColor = color;
    #elif defined(USE_COLOR)
      vColor = vec4(color, 1.0);
    #else
      vColor = vec4(1.0);
    #endif
      gl_Position = projectionMatrix * mv;
    }`,
  fragmentShader: `
    varying vec3 vNormal;
    varying vec3 vView;
    varying vec4 vColor;
    void main() {
      vec3 face = cross(dFdx(vView), dFdy(vView));
      vec3 n = normalize(dot(vNormal, vNormal) < 1e-6 ? face : vNormal);
      float lambert = abs(dot(n, normalize(vView)));
      gl_FragColor = vec4(vColor.rgb * (0.2 + 0.8 * lambert), 1.0);
    }`,
});

const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(innerWidth, innerHeight);
renderer.setClearColor(new THREE.Color(0.09, 0.10, 0.12), 1);
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
document.body.appendChild(renderer.domElement);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(60, innerWidth / innerHeight, 0.1, 1e6);

// The tileset is z-up; the scene, as hlod-view, y-up: the group turns it
// back, and moves the scene's origin (the root's translation) to zero.
const root = await (await fetch(tilesetUrl)).json();
const t = root.root.transform;
const origin = t ? [t[12], t[14], -t[13]] : [0, 0, 0];

const tiles = new TilesRenderer(tilesetUrl);
tiles.registerPlugin(new GLTFExtensionsPlugin({ meshoptDecoder: MeshoptDecoder, metadata: true }));
tiles.errorTarget = errorTarget;
// The cache is bounded by bytes only (its default also caps it at 8,000
// tiles, which the DE-size plant's front exceeds at ε 2 px).
tiles.lruCache.maxBytesSize = cacheMiB * 2 ** 20;
tiles.lruCache.minBytesSize = 0.75 * cacheMiB * 2 ** 20;
tiles.lruCache.maxSize = Infinity;
tiles.lruCache.minSize = 0;
// The library's parse queue is shared by every renderer on the page; it
// starts at most this many parses per animation frame.
tiles.parseQueue.maxJobs = parseJobs;
tiles.group.rotation.x = -Math.PI / 2;
tiles.group.position.set(-origin[0], -origin[1], -origin[2]);
tiles.addEventListener('load-model', ({ scene: model }) => {
  model.traverse((m) => {
    if (m.isMesh) m.material = headlight;
  });
});
tiles.setCamera(camera);
tiles.setResolutionFromRenderer(camera, renderer);
scene.add(tiles.group);

// The whole scene in view at the start, unless a pose is given.
const box = root.root.boundingVolume.box;
const centre = new THREE.Vector3(box[0], box[2], -box[1]);
const radius = Math.hypot(box[3], box[7], box[11]);
camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.5, 0.8).multiplyScalar(radius * 1.6));
camera.lookAt(centre);

const orbit = new OrbitControls(camera, renderer.domElement);
orbit.target.copy(centre);
let fly = false;
const keys = new Set();
addEventListener('keydown', (e) => {
  if (e.key === 'f' || e.key === 'F') {
    fly = !fly;
    orbit.enabled = !fly;
    delete panel.dataset.picked;
    if (!fly) orbit.target.copy(camera.position).add(camera.getWorldDirection(new THREE.Vector3()).multiplyScalar(radius * 0.2));
    status();
  }
  keys.add(e.key.toLowerCase());
});
addEventListener('keyup', (e) => keys.delete(e.key.toLowerCase()));
let drag = null;
renderer.domElement.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, moved: false }; });
addEventListener('pointermove', (e) => {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
  if (fly && drag.moved) {
    const euler = new THREE.Euler().setFromQuaternion(camera.quaternion, 'YXZ');
    euler.y -= dx * 0.004;
    euler.x = Math.max(-1.55, Math.min(1.55, euler.x - dy * 0.004));
    camera.quaternion.setFromEuler(euler);
    drag.x = e.clientX;
    drag.y = e.clientY;
  }
});
addEventListener('pointerup', (e) => {
  if (drag && !drag.moved) show(pick(e.clientX, e.clientY));
  drag = null;
});

function moveFly(dt) {
  const v = new THREE.Vector3(
    (keys.has('d') ? 1 : 0) - (keys.has('a') ? 1 : 0),
    (keys.has('e') ? 1 : 0) - (keys.has('q') ? 1 : 0),
    (keys.has('s') ? 1 : 0) - (keys.has('w') ? 1 : 0),
  );
  if (v.lengthSq() === 0) return;
  v.normalize().multiplyScalar(radius * 0.15 * dt * (keys.has('shift') ? 4 : 1));
  camera.position.add(v.applyQuaternion(camera.quaternion));
}

const raycaster = new THREE.Raycaster();

// The element under pixel (x, y): its properties, or why there is none.
function pick(x, y) {
  const ndc = new THREE.Vector2((x / innerWidth) * 2 - 1, -(y / innerHeight) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(tiles.group, true)[0];
  if (!hit) return null;
  const { meshFeatures, structuralMetadata } = hit.object.userData;
  const point = hit.point.toArray().map((v, i) => v + origin[i]);
  if (!meshFeatures || !structuralMetadata) {
    return { point, element: null, note: 'a simplified group of elements: come closer to name one' };
  }
  const ids = meshFeatures.getFeatures(hit.faceIndex, hit.barycoord || new THREE.Vector3(1, 0, 0));
  const info = meshFeatures.getFeatureInfo();
  if (ids[0] === null) return { point, element: null };
  const element = structuralMetadata.getPropertyTableData(info[0].propertyTable, ids[0]);
  return { point, element };
}

function show(p) {
  if (!p) {
    status();
    return;
  }
  const e = p.element;
  const at = p.point.map((v) => v.toFixed(3)).join(', ');
  if (!e) {
    panel.textContent = `${p.note || 'no element'}\nat ${at}`;
    panel.dataset.picked = '1';
    return;
  }
  const lines = [e.name || `object ${e.object}`];
  if (e.ifc_type) lines.push(`IFC type: ${e.ifc_type}`);
  if (e.global_id) lines.push(`GlobalId: ${e.global_id}`);
  if (e.mesh_name) lines.push(`mesh: ${e.mesh_name}`);
  lines.push(`at ${at}`);
  if (e.info) lines.push(e.info);
  panel.textContent = lines.join('\n');
  panel.dataset.picked = '1';
}

// Bytes the page has downloaded (tileset JSON and tile contents), from the
// browser's resource timing.
let downloaded = 0;
let requests = 0;
new PerformanceObserver((list) => {
  for (const e of list.getEntries()) {
    if (e.name.includes('/node_modules/') || !/\.(glb|json)(\?|$)/.test(e.name)) continue;
    downloaded += e.encodedBodySize || e.transferSize || 0;
    requests += 1;
  }
}).observe({ type: 'resource', buffered: true });

function stats() {
  const s = tiles.stats;
  return {
    downloaded, requests,
    cachedBytes: tiles.lruCache.cachedBytes,
    cacheCap: tiles.lruCache.maxBytesSize,
    queued: s.queued, downloading: s.downloading, parsing: s.parsing,
    loaded: s.loaded, failed: s.failed, visible: tiles.visibleTiles.size,
    triangles: renderer.info.render.triangles, calls: renderer.info.render.calls,
    geometryMemory: renderer.info.memory.geometries,
  };
}

function status() {
  const s = stats();
  panel.textContent = `${fly ? 'fly (W/A/S/D/Q/E, drag to look; F: orbit)' : 'orbit (drag, wheel; F: fly)'}`
    + ` · ε ${errorTarget} px · cache ${(s.cachedBytes / 2 ** 20).toFixed(1)} / ${cacheMiB} MiB`
    + ` · ${s.visible} tiles, ${s.triangles} triangles\nclick an element to name it`;
}

function setPose(p) {
  camera.position.set(p[0], p[1], p[2]);
  camera.quaternion.set(p[3], p[4], p[5], p[6]);
  camera.fov = p[7];
  camera.updateProjectionMatrix();
  orbit.target.copy(camera.position).add(camera.getWorldDirection(new THREE.Vector3()).multiplyScalar(radius * 0.2));
  orbit.update();
  // Orbit controls may re-aim the camera at its target: set it again.
  camera.quaternion.set(p[3], p[4], p[5], p[6]);
}

// Nothing queued, downloading or parsing.
function idle() {
  const s = tiles.stats;
  return !tiles.isLoading && s.queued + s.downloading + s.parsing === 0;
}

// Whether the view is complete: every tile the last update selected (used,
// with content, none of its children used) is loaded. Idle is not enough: a
// full cache loads nothing more and the view shows coarser ancestors.
function complete() {
  const fc = tiles.frameCount;
  const now = (t) => t.traversal.used && t.traversal.lastFrameVisited === fc;
  // Not before the tileset is loaded and traversed (nothing selected yet).
  const root = tiles.root;
  if (!root || root.traversal.lastFrameVisited !== fc) return false;
  for (const t of tiles.usedSet) {
    if (!now(t) || !t.internal.hasRenderableContent || t.children.some(now)) continue;
    if (t.internal.loadingState !== 4) return false;
  }
  return true;
}

addEventListener('resize', () => {
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(innerWidth, innerHeight);
  tiles.setResolutionFromRenderer(camera, renderer);
});

let last = performance.now();
let frames = 0;
function frame(now) {
  const dt = Math.min(0.1, (now - last) / 1000);
  last = now;
  if (fly) moveFly(dt);
  else orbit.update();
  camera.updateMatrixWorld();
  tiles.update();
  renderer.render(scene, camera);
  frames += 1;
  if (frames % 30 === 0 && !panel.dataset.picked) status();
  requestAnimationFrame(frame);
}

const pose = params.get('camera');
if (pose) setPose(pose.split(',').map(Number));
status();
requestAnimationFrame(frame);
window.hlod = { ready: Promise.resolve(), setPose, idle, complete, stats, pick, frames: () => frames };
