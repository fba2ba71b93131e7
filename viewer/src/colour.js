// Colouring features by a column: a ramp for numbers (the preview's height ramp), a palette for classes.

// the stops of sengine's preview.png height ramp (sengine/nodes/export/preview.py)
const RAMP = [
  [255, 240, 170],
  [253, 190, 90],
  [240, 110, 50],
  [190, 40, 70],
  [100, 20, 90],
];
// Tableau 10
const PALETTE = [
  [78, 121, 167],
  [242, 142, 43],
  [225, 87, 89],
  [118, 183, 178],
  [89, 161, 79],
  [237, 201, 72],
  [176, 122, 161],
  [255, 157, 167],
  [156, 117, 95],
  [186, 176, 172],
];
export const MISSING = [200, 200, 200];

export function ramp(t) {
  const x = Math.min(Math.max(t, 0), 1) * (RAMP.length - 1);
  const i = Math.min(Math.floor(x), RAMP.length - 2);
  const f = x - i;
  return RAMP[i].map((c, k) => Math.round(c * (1 - f) + RAMP[i + 1][k] * f));
}

export function rampCss(steps = 8) {
  const stops = [];
  for (let i = 0; i <= steps; i++) stops.push(`rgb(${ramp(i / steps).join(",")})`);
  return `linear-gradient(to right, ${stops.join(",")})`;
}

// The colour modes: which column each names, in order of preference (the first that tells a layer's features apart).
// Buildings carry height, floors, use, typology and far (their lot's, generated ones only); the page adds lot_far,
// the FAR of the lot each building stands on, which map buildings have too; lots carry far.
export const MODES = {
  height: { label: "height", columns: ["height"], numeric: true, unit: "m" },
  floors: { label: "floors", columns: ["floors"], numeric: true, unit: "" },
  use: { label: "use", columns: ["use", "landuse", "building", "district_name", "district", "source"], numeric: false },
  typology: { label: "building type", columns: ["typology"], numeric: false },
  far: { label: "FAR", columns: ["lot_far", "far"], numeric: true, unit: "" },
};

function quantile(sorted, q) {
  if (!sorted.length) return 0;
  const i = Math.min(sorted.length - 1, Math.max(0, Math.round(q * (sorted.length - 1))));
  return sorted[i];
}

function varies(col, n) {
  const first = n ? col.get(0) : null;
  for (let i = 1; i < n; i++) {
    const v = col.get(i);
    if (v !== first && !(Number.isNaN(v) && Number.isNaN(first))) return true;
  }
  return false;
}

// Per-feature colours (Uint8Array, 3 a feature) of `layer` in `mode`, and the legend; null if the layer lacks the column.
export function featureColours(layer, mode) {
  const spec = MODES[mode];
  if (!spec) return null;
  // the first of the mode's columns that tells features apart (two values or more), else the first there is
  const present = spec.columns.map((c) => layer.columns[c]).filter((c) => c);
  if (!present.length) return null;
  const col = present.find((c) => varies(c, layer.features)) || present[0];
  const n = layer.features;
  const out = new Uint8Array(3 * n);
  if (spec.numeric && col.type !== "text") {
    const values = [];
    for (let i = 0; i < n; i++) {
      const v = col.get(i);
      if (v !== null && Number.isFinite(v)) values.push(v);
    }
    values.sort((a, b) => a - b);
    const lo = quantile(values, 0.02);
    const hi = quantile(values, 0.98);
    const span = hi > lo ? hi - lo : 1;
    for (let i = 0; i < n; i++) {
      const v = col.get(i);
      const c = v === null || !Number.isFinite(v) ? MISSING : ramp((v - lo) / span);
      out.set(c, 3 * i);
    }
    return { colours: out, legend: { kind: "ramp", column: col.name, lo, hi, unit: spec.unit } };
  }
  // classes: the most frequent first
  const counts = new Map();
  for (let i = 0; i < n; i++) {
    const v = col.get(i);
    const k = v === null ? null : String(v);
    counts.set(k, (counts.get(k) || 0) + 1);
  }
  const classes = [...counts.entries()].filter(([k]) => k !== null).sort((a, b) => b[1] - a[1] || (a[0] < b[0] ? -1 : 1));
  const colourOf = new Map(classes.map(([k], j) => [k, j < PALETTE.length ? PALETTE[j] : MISSING]));
  for (let i = 0; i < n; i++) {
    const v = col.get(i);
    out.set(v === null ? MISSING : colourOf.get(String(v)), 3 * i);
  }
  const items = classes.slice(0, PALETTE.length).map(([k, c]) => ({ label: k, count: c, colour: colourOf.get(k) }));
  if (classes.length > PALETTE.length) items.push({ label: `${classes.length - PALETTE.length} more`, colour: MISSING });
  return { colours: out, legend: { kind: "classes", column: col.name, items } };
}
