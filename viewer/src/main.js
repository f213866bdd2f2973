// cooprint's plan viewer (docs/viewer.md): the page's entry. Reads the record and the geometry
// the page holds, lays out the view and its controls, plays the plan in real print time, links
// the Gantt chart and the findings, and offers the test hook window.cooprint.

import { readMeta, readGeometry } from './data.js';
import { View } from './scene.js';
import { MODES, legend, TRAVEL_COLOUR } from './colours.js';
import { layout } from './layout.js';
import { clock, css } from './format.js';
import { createGantt } from './gantt.js';
import { createSummary, createFindings } from './panels.js';

// Errors on the page, for the tests (and shown in #notice).
const errors = [];
const hook = { errors };
window.cooprint = hook;
let resolveReady;
hook.ready = new Promise((resolve) => { resolveReady = resolve; });
hook.firstFrameMs = null;
const noteError = (msg) => {
  errors.push(String(msg));
  const n = document.getElementById('notice'), text = document.getElementById('notice-text');
  if (n) { n.hidden = false; (text || n).textContent = `error: ${msg}`; }
};
window.addEventListener('error', (e) => noteError(e.message || e.error || e));
window.addEventListener('unhandledrejection', (e) => noteError((e.reason && (e.reason.stack || e.reason.message)) || e.reason));
const consoleError = console.error.bind(console);
console.error = (...args) => { errors.push(args.map(String).join(' ')); consoleError(...args); };

const SPEEDS = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000, 100000];

async function start() {
  const meta = readMeta();
  const header = meta.geometry;
  const ui = layout(document.body, meta, SPEEDS);
  const geo = await readGeometry(header);
  const view = new View(ui.view, meta, geo);
  const ctx = { robots: meta.robots, header };
  const makespan = meta.makespan;

  // --- state --------------------------------------------------------------------------------
  let t = makespan; // the finished plan first
  let playing = false;
  let speed = SPEEDS.filter((s) => s <= Math.max(makespan / 30, 1)).pop();
  let frames = 0;
  let selected = null;
  let scheduled = false;
  let lastWall = null;
  const eventTimes = [...new Set((meta.events || []).map((e) => e.time_s))].sort((a, b) => a - b);

  // --- the robots at t ----------------------------------------------------------------------
  const facingAt = (rec, time) => {
    const f = rec.facing || [[0, 0]];
    let deg = f[0][1];
    for (const [ft, d] of f) if (ft <= time) deg = d;
    return deg;
  };
  const inIntervals = (list, time) => (list || []).some((iv) => iv[0] <= time && time < iv[1]);
  // nozzle position and state of robot i at time: the segment under way (material or travel), or
  // between two, where the last ended (a wait) or on the way to the next (a thinned gap).
  function robotAt(i, time) {
    const r = geo.robots[i];
    const pos = (paths, v) => [0, 1, 2].map((k) => geo.world(paths.pos[v * 3 + k], k));
    const lerp = (p, q, f) => p.map((x, k) => x + f * (q[k] - x));
    let best = null; // the last segment started by time: {paths, s, kind}
    for (const [paths, kind] of [[r.material, 'printing'], [r.travel, 'travelling']]) {
      const s = paths.started(time) - 1;
      if (s >= 0 && (!best || paths.t0(s) > best.paths.t0(best.s))) best = { paths, s, kind };
    }
    const row = meta.gantt && meta.gantt[i];
    let state = 'idle';
    let position = r.start;
    if (best) {
      const { paths, s } = best;
      const v = paths.start[s];
      if (time <= paths.t1(s)) {
        const f = (time - paths.t0(s)) / Math.max(paths.t1(s) - paths.t0(s), 1e-12);
        position = lerp(pos(paths, v), pos(paths, v + 1), Math.min(Math.max(f, 0), 1));
        state = best.kind;
      } else {
        const end = pos(paths, v + 1), tEnd = paths.t1(s);
        position = end;
        let next = null; // the next segment to start
        for (const p of [r.material, r.travel]) {
          const k = p.started(time);
          if (k < p.count && (!next || p.t0(k) < next.paths.t0(next.k))) next = { paths: p, k };
        }
        if (next) {
          const q = pos(next.paths, next.paths.start[next.k]);
          const dist = Math.hypot(q[0] - end[0], q[1] - end[1], q[2] - end[2]);
          if (dist > 1e-6) position = lerp(end, q, (time - tEnd) / Math.max(next.paths.t0(next.k) - tEnd, 1e-12));
        }
        if (row && inIntervals(row.print, time)) state = 'printing';
        else if (row && inIntervals(row.travel, time)) state = 'travelling';
      }
    }
    const wait = row && (row.wait || []).find((w) => w[0] <= time && time < w[1]);
    if (wait) state = 'waiting';
    if (time >= r.end && r.end > 0 && state !== 'waiting') state = 'done';
    if (r.end === 0 && time > 0) state = 'idle';
    return { position, state, facing: facingAt(meta.robots[i], time), events: wait ? wait[2] || '' : null };
  }

  // Robot i's printing by time: [s done, s in all] (the material's segments' durations, summed
  // once; the segment under way counts up to time), as the PNG snapshot's "% printed".
  const printedSums = [];
  function printedAt(i, time) {
    const m = geo.robots[i].material;
    if (!printedSums[i]) {
      const sums = new Float64Array(m.count + 1);
      for (let s = 0; s < m.count; s++) sums[s + 1] = sums[s] + (m.t1(s) - m.t0(s));
      printedSums[i] = sums;
    }
    const sums = printedSums[i], k = m.ended(time);
    const under = k < m.count && m.t0(k) < time ? Math.min(time, m.t1(k)) - m.t0(k) : 0;
    return [sums[k] + under, sums[m.count]];
  }

  // The robots' status lines (#status): state and share of the printing done, at time.
  const statusRows = meta.robots.map((rec) => {
    const name = document.createElement('span');
    name.className = 'status-name'; name.textContent = rec.name; name.title = `robot ${rec.name}`;
    name.style.color = css(rec.colour);
    const state = document.createElement('span');
    state.className = 'status-state';
    const done = document.createElement('span');
    done.className = 'status-done';
    const row = document.createElement('div');
    row.className = 'status-row';
    row.dataset.robot = rec.name;
    row.append(name, state, done);
    ui.status.appendChild(row);
    return { state, done, last: '' };
  });
  function showStatus(poses, time) {
    poses.forEach((p, i) => {
      const r = statusRows[i];
      if (!r) return;
      const [done, total] = printedAt(i, time);
      const text = p.state === 'waiting' ? `waiting for ${p.events || 'an event'}` : p.state;
      const share = p.state === 'done' ? 100 : Math.floor((100 * done) / total + 1e-9); // (times are rounded to 1 ms)
      const pct = total > 0 ? `${share}% printed` : 'nothing to print';
      if (text + pct === r.last) return;
      r.last = text + pct;
      r.state.textContent = text; r.state.title = text;
      r.done.textContent = pct;
    });
  }
  // --- drawing ------------------------------------------------------------------------------
  const gantt = createGantt(ui.gantt, meta, { onSeek: (x) => seek(x) });
  createSummary(ui.summary, meta);
  const findings = createFindings(ui.findings, meta, { onSelect: (f, i) => selectFinding(i) });
  view.onInvalidate = () => request();

  // One frame at t; returns whether the material is drawn up to t (a large change is drawn over
  // a few frames). The first complete frame resolves cooprint.ready.
  let shown = false;
  function draw() {
    const poses = geo.robots.map((_, i) => robotAt(i, t));
    view.placeRobots(poses);
    showStatus(poses, t);
    const complete = view.render(t);
    frames++;
    ui.slider.value = String(t);
    ui.clock.textContent = `${clock(t)} / ${clock(makespan)}`;
    gantt.setTime(t);
    if (complete && !shown) {
      shown = true;
      requestAnimationFrame(() => { // once it is on the screen
        hook.firstFrameMs = performance.now();
        resolveReady(hook.firstFrameMs);
      });
    }
    return complete;
  }

  function tick(now) {
    scheduled = false;
    if (playing) {
      if (lastWall !== null) t = Math.min(makespan, t + ((now - lastWall) / 1000) * speed);
      lastWall = now;
      if (t >= makespan) setPlaying(false);
    }
    complete = draw();
    if (playing || !complete) request();
    settled();
  }

  // cooprint.idle(): resolved once the page has nothing left to draw (paused, the camera at rest,
  // the last frame complete: a large redraw spread over frames has finished), on the frame after
  // (so that the picture is on the screen).
  let complete = false;
  const idleWaiters = [];
  const isIdle = () => complete && !scheduled && !playing && !view.moving;
  function settled() {
    if (!idleWaiters.length || !isIdle()) return;
    const waiters = idleWaiters.splice(0);
    requestAnimationFrame(() => {
      if (isIdle()) waiters.forEach((w) => w());
      else idleWaiters.push(...waiters); // something changed meanwhile: the next rest
    });
  }
  function idle() {
    return new Promise((resolve) => { idleWaiters.push(resolve); settled(); });
  }

  function request() {
    if (!scheduled) { scheduled = true; requestAnimationFrame(tick); }
  }

  // --- controls -----------------------------------------------------------------------------
  function seek(x) {
    t = Math.min(Math.max(Number(x) || 0, 0), makespan);
    lastWall = null;
    request();
  }
  function setPlaying(on) {
    if (on && t >= makespan) t = 0; // from the start again
    playing = on;
    lastWall = null;
    ui.play.textContent = on ? 'pause' : 'play';
    ui.play.setAttribute('aria-pressed', on ? 'true' : 'false');
    request();
  }
  function setSpeed(x) {
    const v = Math.min(Math.max(Number(x) || 1, 1), 100000);
    speed = v;
    if (![...ui.speed.options].some((o) => Number(o.value) === v)) {
      const o = document.createElement('option');
      o.value = String(v); o.textContent = `${v}x`;
      ui.speed.appendChild(o);
    }
    ui.speed.value = String(v);
    lastWall = null;
  }
  function step(dir) {
    const eps = 1e-6 * Math.max(makespan, 1);
    const next = dir > 0 ? eventTimes.find((e) => e > t + eps) : [...eventTimes].reverse().find((e) => e < t - eps);
    if (next !== undefined) seek(next);
    return next === undefined ? null : next;
  }
  function setColourMode(mode) {
    if (!MODES.some(([m]) => m === mode)) throw new Error(`colour mode ${mode}: expected one of ${MODES.map(([m]) => m)}`);
    const option = [...ui.mode.options].find((o) => o.value === mode);
    if (option && option.disabled) throw new Error(`colour mode ${mode}: ${option.title}`);
    view.setColours(mode, ctx);
    ui.mode.value = mode;
    showLegend();
  }
  function showLegend() {
    const entries = legend(view.colourMode, ctx, geo);
    if (view.showTravel) entries.push({ label: 'travel', colour: [(TRAVEL_COLOUR >> 16) & 255, (TRAVEL_COLOUR >> 8) & 255, TRAVEL_COLOUR & 255] });
    ui.legend.replaceChildren(...entries.map((e) => {
      const row = document.createElement('div');
      row.className = 'legend-row';
      const sw = document.createElement('span');
      sw.className = 'swatch'; sw.style.background = css(e.colour);
      row.append(sw, document.createTextNode(e.label));
      return row;
    }));
  }
  let selecting = false;
  function selectFinding(i) {
    const f = (meta.findings || [])[i];
    if (!f || selecting) return; // (the list's select(i) may call back)
    selecting = true;
    try {
      selected = i;
      view.showMarker(f.position);
      view.lookAt(f.position);
      findings.select(i);
      seek(f.time_s);
    } finally {
      selecting = false;
    }
  }

  ui.play.addEventListener('click', () => setPlaying(!playing));
  ui.speed.addEventListener('change', () => setSpeed(ui.speed.value));
  ui.slider.addEventListener('input', () => seek(ui.slider.value));
  ui.prev.addEventListener('click', () => step(-1));
  ui.next.addEventListener('click', () => step(1));
  ui.mode.addEventListener('change', () => setColourMode(ui.mode.value));
  ui.travel.addEventListener('change', () => { view.setTravel(ui.travel.checked); showLegend(); });
  ui.outlines.addEventListener('change', () => view.setOutlines(ui.outlines.checked));
  const layers = () => {
    let lo = Number(ui.layerLo.value), hi = Number(ui.layerHi.value);
    if (lo > hi) { if (document.activeElement === ui.layerLo) ui.layerHi.value = String(hi = lo); else ui.layerLo.value = String(lo = hi); }
    ui.layerLabel.textContent = `z ${lo.toFixed(1)} - ${hi.toFixed(1)} mm`;
    view.setLayers(lo, hi);
  };
  ui.layerLo.addEventListener('input', layers);
  ui.layerHi.addEventListener('input', layers);
  for (const [b, w] of [[ui.reset, 'reset'], [ui.top, 'top'], [ui.front, 'front'], [ui.side, 'side']]) {
    b.addEventListener('click', () => view.resetView(w));
  }
  // the heights of the material (not the scene's box, which holds the travel's lifts too)
  ui.setLayerRange(0, Math.max(view.partBox.max.z, 0.01), Math.min(...(header.heights.length ? header.heights : [0.2])));
  ui.gridLabel.textContent = `grid ${view.gridStep >= 1000 ? `${view.gridStep / 1000} m` : `${view.gridStep} mm`}`;
  new ResizeObserver(() => { view.resize(); request(); }).observe(ui.view);
  window.addEventListener('keydown', (e) => {
    if (e.target && ['INPUT', 'SELECT', 'TEXTAREA'].includes(e.target.tagName) && e.target.type !== 'range') return;
    if (e.key === ' ') { e.preventDefault(); setPlaying(!playing); }
  });

  // what this plan has no data for: disabled, saying why (a G-code file has no chunks, a
  // single printer's plan may have no events)
  if (!eventTimes.length) {
    for (const b of [ui.prev, ui.next]) {
      b.disabled = true;
      b.title = 'no NOTIFY / WAIT events in this plan';
    }
  }
  if (!legend('chunk', ctx, geo).length) {
    const o = [...ui.mode.options].find((x) => x.value === 'chunk');
    o.disabled = true;
    o.title = 'no chunks in this plan (a G-code file is one piece)';
    o.textContent += ' (no chunks)';
  }

  const th = header.thinned;
  const notes = [];
  if (th) notes.push(`Thinned: showing ${th.shown.toLocaleString('en')} of ${th.total.toLocaleString('en')} material segments, evenly spread: the plan has more than this page holds.`);
  if (header.travel_thinned) notes.push(`Travel: ${header.travel_thinned.shown.toLocaleString('en')} of ${header.travel_thinned.total.toLocaleString('en')} moves shown.`);
  if (notes.length) ui.showNotice(notes.join(' '));

  // --- the test hook (tests/test_viewer_browser.py, benchmarks) --------------------------------
  Object.assign(hook, {
    makespan,
    time: () => t,
    seek: (x) => { seek(x); },
    play: () => setPlaying(true),
    pause: () => setPlaying(false),
    playing: () => playing,
    setSpeed,
    speed: () => speed,
    nextEvent: () => step(1),
    prevEvent: () => step(-1),
    setColourMode,
    colourMode: () => view.colourMode,
    robotState: (name) => {
      const i = geo.robots.findIndex((r) => r.name === name);
      if (i < 0) return null;
      const s = robotAt(i, t);
      const [done, total] = printedAt(i, t);
      return { position: s.position, state: s.state, events: s.events, printed: total > 0 ? done / total : null };
    },
    frames: () => frames,
    selectedFinding: () => selected,
    selectFinding,
    thinned: () => (th ? { shown: th.shown, total: th.total } : null),
    idle,
    gridStep: () => view.gridStep,
  });
  setSpeed(speed);
  setColourMode('robot');
  request();
}

start().catch((e) => noteError((e && (e.stack || e.message)) || e));
