// Reading city.view.js: the object `window.SENGINE_VIEW` that `sengine view` / `--format html` writes.
//
// {format: "sengine-view", version: 1, name, attribution, crs, origin: {lat, lon}, bounds: [x0, y0, z0, x1, y1, z1],
//  plan: "preview.png" | null,
//  layers: [{name, colour: [r, g, b], kind: "solid" | "surface" | "line", level, vertices, triangles, features,
//            position: offset (float32 x, y, z; y up, metres around the city's origin),
//            index: offset (uint32, 3 a triangle), feature: offset (float32, the row of each vertex's feature),
//            tiles: [[first triangle, upward triangles, triangles, x0, y0, z0, x1, y1, z1, upward triangles of the
//                     features 8, 16, 32, 64 m across]], scale: a feature's size (m),
//            columns: [{name, type: "float" | "int" | "bool" | "text", offset, values?: [...], width?: 1 | 2 | 4}]}],
//  bin: base64 of every array, each at its offset (8-byte aligned), in strings of 12 MB each (one string of
//       hundreds of MB parses 25 times slower); a single string in files written before}

export function decodeBase64(text) {
  if (typeof Uint8Array.fromBase64 === "function") return Uint8Array.fromBase64(text);
  const s = atob(text);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

// A column as a function row -> value (null for missing).
function columnReader(buffer, n, col) {
  if (col.type === "float") {
    const a = new Float64Array(buffer, col.offset, n);
    return { name: col.name, type: col.type, array: a, get: (i) => (Number.isNaN(a[i]) ? null : a[i]) };
  }
  if (col.type === "int") {
    const a = new Int32Array(buffer, col.offset, n);
    return { name: col.name, type: col.type, array: a, get: (i) => a[i] };
  }
  if (col.type === "bool") {
    const a = new Uint8Array(buffer, col.offset, n);
    return { name: col.name, type: col.type, array: a, get: (i) => (a[i] === 2 ? null : a[i] === 1) };
  }
  // text (and anything else): a code per row into `values`
  const Codes = col.width === 1 ? Uint8Array : col.width === 2 ? Uint16Array : Uint32Array;
  const codes = new Codes(buffer, col.offset, n);
  const values = col.values;
  return { name: col.name, type: "text", codes, values, get: (i) => values[codes[i]] };
}

// The arrays of `bin`: one base64 string, or several whose decoded bytes follow each other.
function decodeBin(bin) {
  if (typeof bin === "string") return decodeBase64(bin);
  const parts = bin.map(decodeBase64);
  const out = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
  let at = 0;
  for (const p of parts) {
    out.set(p, at);
    at += p.length;
  }
  return out;
}

export function readView(view) {
  if (!view || view.format !== "sengine-view") throw new Error("city.view.js holds no sengine view data");
  const bytes = decodeBin(view.bin);
  const buffer = bytes.buffer;
  const layers = view.layers.map((l) => {
    const columns = {};
    for (const c of l.columns) columns[c.name] = columnReader(buffer, l.features, c);
    return {
      name: l.name,
      colour: l.colour,
      kind: l.kind,
      level: l.level,
      vertices: l.vertices,
      triangles: l.triangles,
      features: l.features,
      position: new Float32Array(buffer, l.position, 3 * l.vertices),
      index: new Uint32Array(buffer, l.index, 3 * l.triangles),
      feature: new Float32Array(buffer, l.feature, l.vertices),
      tiles: l.tiles || [[0, l.triangles, l.triangles, ...l.bounds]],
      scale: l.scale || 0,
      columns,
    };
  });
  return { ...view, layers };
}
