// The page's data: the JSON record (meta: panels, Gantt, robots; meta.geometry: the buffers'
// header) and the geometry's buffers (gzip + base64 in a <script>), decoded into typed arrays.
// Layout and codecs: src/cooprint/render/viewer/geometry.py (docs/viewer.md).

export function readMeta() {
  return JSON.parse(document.getElementById('cooprint-meta').textContent);
}

// base64 -> bytes -> gunzip (the browser's DecompressionStream): the payload's bytes.
async function payload() {
  const text = document.getElementById('cooprint-geometry').textContent.trim();
  const bin = atob(text);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

const SIZES = { u1: 1, i1: 1, u2: 2, i2: 2, u4: 4, i4: 4 };
const TYPES = { u1: Uint8Array, i1: Int8Array, u2: Uint16Array, i2: Int16Array, u4: Uint32Array, i4: Int32Array };

// One array of the payload: raw (little-endian, 8-byte aligned) or its bytes in planes ("shuffle":
// all first bytes, then all second bytes...; a (n, 3) array column by column).
function array(bytes, d) {
  const size = SIZES[d.dtype];
  const n = d.shape.reduce((a, b) => a * b, 1);
  const Type = TYPES[d.dtype];
  if (d.codec !== 'shuffle') return new Type(bytes.buffer, bytes.byteOffset + d.offset, n);
  const out = new Type(n);
  const raw = bytes.subarray(d.offset, d.offset + d.bytes);
  const rows = d.shape[0], cols = d.shape.length === 2 ? d.shape[1] : 1;
  for (let c = 0; c < cols; c++) {
    const base = c * size * rows;
    for (let i = 0; i < rows; i++) {
      let v = 0;
      for (let b = size - 1; b >= 0; b--) v = v * 256 + raw[base + b * rows + i];
      out[i * cols + c] = v;
    }
  }
  return out;
}

// A robot's polylines of one kind: vertices (positions quantized uint16 xyz, times s) and the
// segments between consecutive vertices of a polyline, in time order.
export class Paths {
  constructor(pos, time, lengths) {
    this.pos = pos; // Uint16Array (vertices * 3), quantized over the scene's box
    this.time = time; // Float64Array (vertices), s
    const nseg = time.length - lengths.length;
    const start = new Uint32Array(nseg); // each segment's first vertex
    let v = 0, s = 0;
    for (let p = 0; p < lengths.length; p++) {
      const n = lengths[p];
      for (let k = 0; k < n - 1; k++) start[s++] = v + k;
      v += n;
    }
    this.start = start;
    this.count = nseg;
  }

  t0(s) { return this.time[this.start[s]]; }
  t1(s) { return this.time[this.start[s] + 1]; }

  // How many segments have ended by t (their end time <= t).
  ended(t) {
    let lo = 0, hi = this.count;
    while (lo < hi) {
      const mid = (lo + hi) >>> 1;
      if (this.time[this.start[mid] + 1] <= t) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  // How many segments have started by t (their start time <= t).
  started(t) {
    let lo = 0, hi = this.count;
    while (lo < hi) {
      const mid = (lo + hi) >>> 1;
      if (this.time[this.start[mid]] <= t) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  // Two vertices per segment (for gl.LINES), quantized.
  segmentPositions() {
    const out = new Uint16Array(this.count * 6);
    const pos = this.pos, start = this.start;
    for (let s = 0; s < this.count; s++) {
      const a = start[s] * 3, o = s * 6;
      out[o] = pos[a]; out[o + 1] = pos[a + 1]; out[o + 2] = pos[a + 2];
      out[o + 3] = pos[a + 3]; out[o + 4] = pos[a + 4]; out[o + 5] = pos[a + 5];
    }
    return out;
  }
}

// Runs (start index, value) over n items -> the value of each item.
function expand(at, values, n) {
  const out = new Int32Array(n);
  for (let r = 0; r < at.length; r++) {
    const end = r + 1 < at.length ? at[r + 1] : n;
    out.fill(values[r], at[r], end);
  }
  return out;
}

// Everything the scene draws: per robot its material (with chunk, role, height index per
// segment) and travel; the chunks' outline edges; the scene's box.
export async function readGeometry(header) {
  const bytes = await payload();
  const dir = header.directory;
  const get = (name) => array(bytes, dir[name]);
  const qmax = header.qmax;
  const positions = (name) => { // deltas modulo 2^16 -> absolute
    const d = get(name);
    const out = new Uint16Array(d.length);
    let x = 0, y = 0, z = 0;
    for (let i = 0; i < d.length; i += 3) {
      x = (x + d[i]) & 0xffff; y = (y + d[i + 1]) & 0xffff; z = (z + d[i + 2]) & 0xffff;
      out[i] = x; out[i + 1] = y; out[i + 2] = z;
    }
    return out;
  };
  const times = (name) => { // deltas in time units -> s
    const d = get(name);
    const out = new Float64Array(d.length);
    let acc = 0;
    for (let i = 0; i < d.length; i++) { acc += d[i]; out[i] = acc * header.time_unit; }
    return out;
  };
  const robots = header.robots.map((rec, i) => {
    const paths = (kind) => new Paths(positions(`${i}/${kind}/pos`), times(`${i}/${kind}/time`),
                                      get(`${i}/${kind}/lengths`));
    const material = paths('material');
    for (const attr of ['chunk', 'role', 'height']) {
      material[attr] = expand(get(`${i}/material/${attr}_at`), get(`${i}/material/${attr}`), material.count);
    }
    return { name: rec.name, start: rec.start, end: rec.end, material, travel: paths('travel') };
  });
  const outline = positions('outlines/pos');
  const lo = header.lo, hi = header.hi;
  const span = [0, 1, 2].map((k) => Math.max(hi[k] - lo[k], 1e-6));
  return {
    robots, outline, lo, hi, span, qmax,
    // quantized -> mm
    world(q, k) { return lo[k] + (q / qmax) * span[k]; },
  };
}
