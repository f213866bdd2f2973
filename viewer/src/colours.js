// The material's colours in each mode, and the legend that explains them. Robot colours come
// from the page's record (cooprint.render.palette, the same as every picture); role colours
// from cooprint.render.paths.ROLE_COLOURS (the geometry header's roles).

export const MODES = [
  ['robot', 'per robot'], ['chunk', 'per chunk'], ['role', 'per role'], ['height', 'per layer height'],
];
export const TRAVEL_COLOUR = 0xaaaaaa;

// A chunk's colour: hues by the golden angle (each as far as it can be from those before).
function chunkColour(i) {
  const h = (0.6 + i * 0.381966) % 1, s = [0.65, 0.5, 0.8][i % 3], v = [0.85, 0.65, 0.75][i % 3];
  return hsv(h, s, v);
}

function hsv(h, s, v) {
  const i = Math.floor(h * 6), f = h * 6 - i, p = v * (1 - s), q = v * (1 - f * s), t = v * (1 - (1 - f) * s);
  const [r, g, b] = [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v], [v, p, q]][i % 6];
  return [Math.round(r * 255), Math.round(g * 255), Math.round(b * 255)];
}

// Layer heights from thin to thick: blue to yellow (viridis' ends and middle).
function heightColour(f) {
  const stops = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  const x = Math.min(Math.max(f, 0), 1) * (stops.length - 1), i = Math.min(Math.floor(x), stops.length - 2), u = x - i;
  return stops[i].map((c, k) => Math.round(c + u * (stops[i + 1][k] - c)));
}

function heightColours(heights) {
  const lo = Math.min(...heights), hi = Math.max(...heights);
  return heights.map((h) => heightColour(hi > lo ? (h - lo) / (hi - lo) : 0.5));
}

// colourTable(mode, robot index, its material (per segment chunk, role, height index), context)
// -> {per(segment) -> [r, g, b] bytes}; context: {robots: meta.robots, header: meta.geometry}.
export function colourTable(mode, robot, material, ctx) {
  const { robots, header } = ctx;
  if (mode === 'chunk') {
    const table = header.chunks.map((_, i) => chunkColour(i));
    const none = [150, 150, 150];
    return { per: (s) => (material.chunk[s] >= 0 ? table[material.chunk[s]] : none) };
  }
  if (mode === 'role') {
    const table = header.roles.map((r) => r.colour);
    return { per: (s) => table[material.role[s]] || [0, 0, 0] };
  }
  if (mode === 'height') {
    const table = heightColours(header.heights.length ? header.heights : [0]);
    return { per: (s) => table[material.height[s]] || table[0] };
  }
  const c = robots[robot].colour;
  return { per: () => c };
}

// The legend's entries for a mode: [{label, colour}] (those present in the plan).
export function legend(mode, ctx, geo) {
  const { robots, header } = ctx;
  const present = (attr) => {
    const seen = new Set();
    for (const r of geo.robots) for (const v of r.material[attr]) seen.add(v);
    return seen;
  };
  if (mode === 'chunk') {
    const seen = present('chunk');
    return header.chunks.map((id, i) => ({ label: `chunk ${id}`, colour: chunkColour(i), shown: seen.has(i) }))
      .filter((e) => e.shown);
  }
  if (mode === 'role') {
    const seen = present('role');
    return header.roles.map((r, i) => ({ label: r.name, colour: r.colour, shown: seen.has(i) })).filter((e) => e.shown);
  }
  if (mode === 'height') {
    const seen = present('height');
    const cols = heightColours(header.heights.length ? header.heights : [0]);
    return header.heights.map((h, i) => ({ label: `${h.toFixed(3).replace(/0+$/, '').replace(/\.$/, '')} mm layers`,
                                           colour: cols[i], shown: seen.has(i) })).filter((e) => e.shown);
  }
  return robots.map((r) => ({ label: `robot ${r.name}`, colour: r.colour }));
}
