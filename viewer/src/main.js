// The sengine city viewer: the city of city.view.js in 3D (three.js), layers on and off, features coloured by
// height, use or FAR, a click shows a feature's attributes.  Works from file:// (the data comes in a <script>).
import * as THREE from "three";
import { MapControls } from "three/examples/jsm/controls/MapControls.js";
import { featureColours, MODES, rampCss } from "./colour.js";
import { readView } from "./data.js";
import { createPicker } from "./pick.js";

const $ = (sel) => document.querySelector(sel);
const SIZES = [8, 16, 32, 64]; // m: feature sizes each tile counts its roofs for (sengine.viewer.SIZES)
// sRGB 0-255 to linear 0-255 (the sRGB transfer function)
const LINEAR = Uint8Array.from({ length: 256 }, (_, c) => {
  const x = c / 255;
  return Math.round(255 * (x <= 0.04045 ? x / 12.92 : ((x + 0.055) / 1.055) ** 2.4));
});

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c);
  return e;
}

// identifiers and references (id, osm_id, lot, block, district ...) are shown as written, without thousands separators
const IDENTIFIER = /(^|_)id$|^(lot|block|district|face|parent)$/;

function fmt(v, name = "") {
  if (v === null || v === undefined) return "–";
  if (typeof v === "number") {
    if (Number.isInteger(v)) return IDENTIFIER.test(name) ? String(v) : v.toLocaleString("en");
    return String(Number(v.toPrecision(7)));
  }
  return String(v);
}

function isSoftware() {
  try {
    const gl = document.createElement("canvas").getContext("webgl2");
    const ext = gl && gl.getExtension("WEBGL_debug_renderer_info");
    const name = gl ? String(gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER)) : "";
    gl?.getExtension("WEBGL_lose_context")?.loseContext();
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  } catch {
    return false;
  }
}

function start() {
  // where the time to open a city goes (ms): reading and parsing the scripts, decoding, building, colouring, a frame
  const timings = { scripts: Math.round(performance.now()) };
  let mark = performance.now();
  const lap = (name) => {
    const now = performance.now();
    timings[name] = Math.round(now - mark);
    mark = now;
  };
  const view = readView(window.SENGINE_VIEW);
  lap("decode");
  const host = $("#view");
  // a software rasteriser draws without multisampling (it costs it 2.5 times the time of a frame)
  const software = isSoftware();
  const renderer = new THREE.WebGLRenderer({ antialias: !software, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setClearColor(0xf4f3ef);
  host.append(renderer.domElement);

  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8478, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.9);
  sun.position.set(-0.55, 1.0, 0.35);
  scene.add(sun);

  const [x0, y0, z0, x1, y1, z1] = view.home || view.bounds; // the city without its outliers (a long road out)
  const span = Math.max(x1 - x0, z1 - z0, y1 - y0, 1);
  const centre = new THREE.Vector3((x0 + x1) / 2, 0, (z0 + z1) / 2);

  const camera = new THREE.PerspectiveCamera(45, 1, 1, 10 * span);
  const controls = new MapControls(camera, renderer.domElement);
  controls.enableDamping = false;
  controls.maxPolarAngle = Math.PI * 0.495;
  controls.minDistance = 2;
  controls.maxDistance = 6 * span;
  controls.zoomToCursor = true;
  controls.listenToKeyEvents(window);

  // the whole city in view, seen from the south-south-west at 50 degrees: the camera backs off until the corners of
  // the city's bounds fill 90 % of the view
  function home() {
    const up = THREE.MathUtils.degToRad(50);
    const turn = THREE.MathUtils.degToRad(-20);
    const dir = new THREE.Vector3(Math.cos(up) * Math.sin(turn), Math.sin(up), Math.cos(up) * Math.cos(turn));
    const corners = [];
    for (const x of [x0, x1]) for (const y of [0, y1]) for (const z of [z0, z1]) corners.push(new THREE.Vector3(x, y, z));
    controls.target.copy(centre);
    let d = span;
    for (let i = 0; i < 4; i++) {
      camera.position.copy(centre).addScaledVector(dir, d);
      camera.lookAt(centre);
      camera.near = d / 100;
      camera.far = 10 * d;
      camera.updateProjectionMatrix();
      camera.updateMatrixWorld();
      let m = 0;
      for (const c of corners) {
        const p = c.clone().project(camera);
        m = Math.max(m, Math.abs(p.x), Math.abs(p.y));
      }
      d *= m / 0.9;
    }
    camera.position.copy(centre).addScaledVector(dir, d);
    controls.update();
    redraw();
  }

  // each layer: one material, its arrays uploaded once, and a mesh per tile (a draw range of its triangles) so that
  // tiles out of view are skipped and far ones lose their detail; flat layers drawn later are pulled forward
  const meshes = new Map();
  const tileMeshes = [];
  view.layers.forEach((layer, k) => {
    const position = new THREE.BufferAttribute(layer.position, 3);
    const fid = new THREE.BufferAttribute(layer.feature, 1);
    const index = new THREE.BufferAttribute(layer.index, 1);
    const solid = layer.kind === "solid";
    const colour = new THREE.Color().setRGB(...layer.colour.map((c) => c / 255), THREE.SRGBColorSpace);
    // the ground (flat layers, a few centimetres apart) is painted layer over layer without a depth test, before
    // the solids, which are then tested against it: no depth fighting however far the camera is
    // (flat ground needs no lighting: an unlit material draws it as its colour, at a fraction of the cost)
    const material = solid
      ? new THREE.MeshLambertMaterial({ color: colour, flatShading: true, side: THREE.FrontSide })
      : new THREE.MeshBasicMaterial({ color: colour, side: THREE.DoubleSide, depthTest: false });
    const group = new THREE.Group();
    group.name = layer.name;
    const entry = { layer, group, material, colour, position, index, tiles: [], pickIndex: k + 1, order: solid ? 1000 + k : k };
    for (const [first, up, count, tx0, ty0, tz0, tx1, ty1, tz1, ...bySize] of layer.tiles) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute("position", position);
      geometry.setAttribute("fid", fid);
      geometry.setIndex(index);
      geometry.setDrawRange(3 * first, 3 * count);
      geometry.boundingBox = new THREE.Box3(new THREE.Vector3(tx0, ty0, tz0), new THREE.Vector3(tx1, ty1, tz1));
      geometry.boundingSphere = geometry.boundingBox.getBoundingSphere(new THREE.Sphere());
      const mesh = new THREE.Mesh(geometry, material);
      mesh.name = layer.name;
      mesh.userData = { first, up, count, bySize, index: k + 1, entry };
      mesh.matrixAutoUpdate = false;
      mesh.renderOrder = solid ? 1000 + k : k;
      group.add(mesh);
      entry.tiles.push(mesh);
      tileMeshes.push(mesh);
    }
    scene.add(group);
    meshes.set(layer.name, entry);
  });

  // Detail by distance, where it cannot be seen: a solid tile keeps only its upward faces (roofs) when its typical
  // feature's height is under 3 pixels, and only the roofs of features a pixel and a half across; a surface tile is left out when it has more triangles than the pixels it
  // covers (lots seen from afar; blocks and streets stay), ribbons when they are under a pixel wide.
  function levelOfDetail() {
    const h = renderer.domElement.clientHeight || 1;
    const k = h / (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2));
    for (const mesh of tileMeshes) {
      const { first, up, count, bySize, entry } = mesh.userData;
      const b = mesh.geometry.boundingBox;
      const d = Math.max(b.distanceToPoint(camera.position), 1);
      const px = k / d; // pixels a metre
      const kind = entry.layer.kind;
      if (kind === "solid") {
        // walls when they are 3 pixels tall; else roofs, of the features over a pixel and a half across
        let n = entry.layer.scale * px >= 3 ? count : up;
        if (n === up && bySize.length === SIZES.length) {
          const smallest = 1.5 / px; // m
          for (let i = SIZES.length - 1; i >= 0; i--) if (SIZES[i] <= smallest) { n = bySize[i]; break; }
        }
        mesh.visible = n > 0;
        mesh.geometry.setDrawRange(3 * first, 3 * n);
      } else if (kind === "line") {
        mesh.visible = !(entry.layer.scale > 0) || entry.layer.scale * px >= 1;
      } else {
        mesh.visible = count <= (b.max.x - b.min.x) * (b.max.z - b.min.z) * px * px;
      }
    }
  }

  const picker = createPicker(renderer, scene, camera, tileMeshes);
  let highlight = null;
  let selected = null;

  let needsRender = true;
  function redraw() {
    needsRender = true;
  }
  // On a software rasteriser (SwiftShader, llvmpipe) or when a frame takes long, frames drawn while the camera moves
  // are drawn at half resolution; the frame once it rests at full resolution.
  const fullRatio = renderer.getPixelRatio();
  let slow = software;
  let moving = false;
  let restTimer = 0;
  function render() {
    const d = camera.position.distanceTo(controls.target);
    camera.near = Math.max(0.2, d / 400);
    camera.far = Math.max(4 * d, 3 * span) + d;
    camera.updateProjectionMatrix();
    const ratio = moving && slow ? fullRatio / 2 : fullRatio;
    if (renderer.getPixelRatio() !== ratio) renderer.setPixelRatio(ratio);
    levelOfDetail();
    const t = performance.now();
    renderer.render(scene, camera);
    if (!moving) slow = software || performance.now() - t > 40;
  }
  function moved() {
    moving = true;
    clearTimeout(restTimer);
    restTimer = setTimeout(() => {
      moving = false;
      redraw();
    }, 250);
    redraw();
  }
  controls.addEventListener("change", moved);

  function resize() {
    const w = host.clientWidth;
    const h = host.clientHeight;
    renderer.setSize(w, h);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    redraw();
  }
  window.addEventListener("resize", resize);

  // -- panel: layers, colours, legend, selection ---------------------------------------------------------------
  $("#title").textContent = view.name || "sengine city";
  document.title = `${view.name || "city"} · sengine`;
  const counts = view.layers.map((l) => `${l.features.toLocaleString("en")} ${l.name}`).join(" · ");
  $("#subtitle").textContent = counts;
  const list = $("#layers");
  for (const layer of view.layers) {
    const box = el("input", { type: "checkbox", "data-layer": layer.name });
    box.checked = true;
    box.addEventListener("change", () => setLayerVisible(layer.name, box.checked));
    const swatch = el("span", { class: "swatch", style: `background: rgb(${layer.colour.join(",")})` });
    list.append(el("label", {}, box, swatch, ` ${layer.name} `, el("small", {}, layer.features.toLocaleString("en"))));
  }
  const select = $("#colour");
  select.append(el("option", { value: "layer" }, "layer colours"));
  for (const [key, spec] of Object.entries(MODES)) {
    if (view.layers.some((l) => spec.columns.some((c) => l.columns[c])))
      select.append(el("option", { value: key }, spec.label));
  }
  select.addEventListener("change", () => setColourMode(select.value));

  function setLayerVisible(name, on) {
    const entry = meshes.get(name);
    if (!entry) throw new Error(`no layer ${name}`);
    entry.group.visible = on;
    const box = list.querySelector(`input[data-layer="${name}"]`);
    if (box) box.checked = on;
    if (highlight && highlight.userData.layer === name) highlight.visible = on;
    redraw();
  }

  function setColourMode(mode) {
    const legend = $("#legend");
    legend.replaceChildren();
    let shown = null;
    // buildings decide the legend; other layers with the column are coloured alike
    const order = [...meshes.values()].sort((a, b) => (b.layer.kind === "solid") - (a.layer.kind === "solid"));
    for (const entry of order) {
      const layer = entry.layer;
      const result = mode === "layer" ? null : featureColours(layer, mode);
      if (!result) {
        entry.material.vertexColors = false;
        entry.material.color.copy(entry.colour);
      } else {
        const colours = result.colours.map((c) => LINEAR[c]); // vertex colours are linear in three.js
        const n = layer.vertices;
        const v = new Uint8Array(3 * n);
        const f = layer.feature;
        for (let i = 0; i < n; i++) {
          const j = 3 * f[i];
          v[3 * i] = colours[j];
          v[3 * i + 1] = colours[j + 1];
          v[3 * i + 2] = colours[j + 2];
        }
        const attr = new THREE.BufferAttribute(v, 3, true);
        for (const mesh of entry.tiles) mesh.geometry.setAttribute("color", attr);
        entry.material.vertexColors = true;
        entry.material.color.set(0xffffff);
        if (!shown) shown = { layer: layer.name, ...result.legend };
      }
      entry.material.needsUpdate = true;
    }
    if (shown && shown.kind === "ramp") {
      legend.append(
        el("div", {}, `${shown.layer}: ${shown.column}`),
        el("div", { class: "ramp", style: `background: ${rampCss()}` }),
        el("div", { class: "ends" }, el("span", {}, fmt(shown.lo) + (shown.unit ? ` ${shown.unit}` : "")), el("span", {}, fmt(shown.hi) + (shown.unit ? ` ${shown.unit}` : ""))),
      );
    } else if (shown) {
      legend.append(el("div", {}, `${shown.layer}: ${shown.column}`));
      for (const item of shown.items)
        legend.append(el("div", { class: "item" }, el("span", { class: "swatch", style: `background: rgb(${item.colour.join(",")})` }), ` ${item.label}`));
    }
    select.value = mode;
    redraw();
  }

  function rowsOf(layer, row) {
    const rows = [];
    for (const [name, col] of Object.entries(layer.columns)) rows.push([name, col.get(row)]);
    return rows;
  }

  function select_(hit) {
    if (highlight) {
      scene.remove(highlight);
      highlight.geometry.dispose();
      highlight = null;
    }
    selected = hit;
    const info = $("#info");
    info.replaceChildren();
    if (!hit) {
      info.append(el("p", { class: "hint" }, "Click a building or a lot to see its attributes."));
      redraw();
      return;
    }
    const layer = view.layers.find((l) => l.name === hit.layer);
    const idCol = layer.columns.id;
    const id = idCol ? idCol.get(hit.row) : hit.row;
    info.append(el("h3", { id: "picked", "data-layer": hit.layer, "data-id": String(id) }, `${hit.layer} ${fmt(id, "id")}`));
    const table = el("table");
    for (const [k, v] of rowsOf(layer, hit.row)) table.append(el("tr", {}, el("th", {}, k), el("td", {}, fmt(v, k))));
    info.append(table);
    highlight = picker.highlightMesh(meshes.get(hit.layer), hit.row);
    highlight.visible = meshes.get(hit.layer).group.visible;
    highlight.userData.layer = hit.layer;
    scene.add(highlight);
    redraw();
  }

  function pickAt(x, y) {
    const hit = picker.pick(x, y, renderer.domElement.clientWidth, renderer.domElement.clientHeight);
    select_(hit);
    return hit ? { layer: hit.layer, row: hit.row, id: view.layers.find((l) => l.name === hit.layer).columns.id?.get(hit.row) ?? hit.row } : null;
  }

  let down = null;
  renderer.domElement.addEventListener("pointerdown", (e) => {
    down = e.button === 0 ? [e.clientX, e.clientY] : null;
  });
  renderer.domElement.addEventListener("pointerup", (e) => {
    if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const r = renderer.domElement.getBoundingClientRect();
    pickAt(e.clientX - r.left, e.clientY - r.top);
  });

  // -- a feature's place, for focusing on it ---------------------------------------------------------------------
  function featureBox(name, row) {
    const layer = view.layers.find((l) => l.name === name);
    const box = new THREE.Box3();
    const p = layer.position;
    const f = layer.feature;
    const v = new THREE.Vector3();
    for (let i = 0; i < layer.vertices; i++) if (f[i] === row) box.expandByPoint(v.set(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
    return box;
  }

  function rowOf(name, id) {
    const layer = view.layers.find((l) => l.name === name);
    const col = layer.columns.id;
    if (!col) return id;
    for (let i = 0; i < layer.features; i++) if (col.get(i) === id) return i;
    return -1;
  }

  // Look at a feature's top from `distance` m away, `elevation` degrees above the horizon (90: straight down, from
  // the south-south-west otherwise); return where it is on the screen.
  function focus(name, id, distance = 120, elevation = 90) {
    const row = rowOf(name, id);
    if (row < 0) throw new Error(`no ${name} ${id}`);
    const box = featureBox(name, row);
    const c = box.getCenter(new THREE.Vector3());
    const up = THREE.MathUtils.degToRad(Math.min(elevation, 89.94));
    const turn = THREE.MathUtils.degToRad(-20);
    controls.target.set(c.x, box.max.y, c.z);
    camera.position.set(
      c.x + distance * Math.cos(up) * Math.sin(turn),
      box.max.y + distance * Math.sin(up),
      c.z + distance * Math.cos(up) * Math.cos(turn),
    );
    controls.update();
    render();
    needsRender = false;
    return { x: renderer.domElement.clientWidth / 2, y: renderer.domElement.clientHeight / 2 };
  }

  // Where the top centre of a feature is on the canvas (CSS pixels), or null when off screen.
  function screenOf(name, id) {
    const row = rowOf(name, id);
    if (row < 0) return null;
    const b = featureBox(name, row);
    const p = new THREE.Vector3((b.min.x + b.max.x) / 2, b.max.y, (b.min.z + b.max.z) / 2).project(camera);
    if (Math.abs(p.x) > 1 || Math.abs(p.y) > 1 || p.z > 1) return null;
    return { x: ((p.x + 1) / 2) * renderer.domElement.clientWidth, y: ((1 - p.y) / 2) * renderer.domElement.clientHeight };
  }

  // Frames per second while orbiting: the camera circles the city and every frame is drawn.
  function measureFps(seconds = 5) {
    return new Promise((resolve) => {
      let frames = 0;
      const t0 = performance.now();
      const radius = Math.hypot(camera.position.x - controls.target.x, camera.position.z - controls.target.z);
      const height = camera.position.y;
      measuring = true;
      function tick(now) {
        const t = (now - t0) / 1000;
        const a = t * 0.6;
        camera.position.set(controls.target.x + radius * Math.sin(a), height, controls.target.z + radius * Math.cos(a));
        camera.lookAt(controls.target);
        moving = t < seconds;
        render();
        frames++;
        if (t < seconds) requestAnimationFrame(tick);
        else {
          measuring = false;
          controls.update();
          resolve({ frames, seconds: t, fps: frames / t });
        }
      }
      requestAnimationFrame(tick);
    });
  }

  let measuring = false;
  function loop() {
    if (needsRender && !measuring) {
      render();
      needsRender = false;
    }
    requestAnimationFrame(loop);
  }

  $("#home").addEventListener("click", home);
  if (view.attribution) $("#attribution").textContent = view.attribution;
  if (view.plan) {
    const img = $("#plan img");
    img.addEventListener("load", () => ($("#plan").hidden = false));
    img.src = view.plan;
  }

  lap("build");
  resize();
  home();
  setColourMode(select.querySelector('option[value="height"]') ? "height" : "layer");
  select_(null);
  lap("colour");
  render();
  renderer.getContext().finish();
  lap("first_frame");
  needsRender = false;
  loop();

  window.sengineViewer = {
    ready: true,
    layers: view.layers.map((l) => l.name),
    setLayerVisible,
    setColourMode,
    pickAt,
    focus,
    screenOf,
    view,
    home,
    measureFps,
    render: () => render(),
    drawn: () => ({ ...renderer.info.render }), // the last frame's draw calls and triangles
    selected: () => selected,
    triangles: view.layers.reduce((s, l) => s + l.triangles, 0),
    timings,
  };
  document.body.dataset.ready = "1";
}

try {
  start();
} catch (err) {
  const box = document.querySelector("#error");
  if (box) {
    box.hidden = false;
    box.textContent = `The viewer could not start: ${err.message}`;
  }
  document.body.dataset.ready = "error";
  throw err;
}
