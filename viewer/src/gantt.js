// The Gantt chart under the 3D view:
//   createGantt(el, meta, {onSeek(t)}) -> {setTime(t)}
// el: a <div> to fill (its width: the chart follows it; its height: the chart's own, a header,
// the rows and the axis, so the page should let it grow or scroll); meta: the page's JSON record
// (render/viewer/meta.py: meta.gantt rows, meta.robots colours, meta.makespan,
// meta.critical_path, meta.lower_bound, meta.colours, meta.gantt_resolution_s).
//
// One row per robot (its name in its colour; rows thin out down to 10 px for 64 robots): its
// printing in its colour, its travelling as a grey strip under it, as tall as the share of the
// time it travels (as the PNG chart's; at least a pixel wherever it travels, at any zoom), its waits in yellow (what it waits for in the tooltip), each chunk's id on
// its bar where it fits, the critical path's chunks framed in red, the lower bound as a dashed
// line, a time axis in h:mm ("1 d 04:00" from a day on). The chart is drawn on one canvas when the
// width, the zoom or the pixel ratio change; the time cursor on a second canvas over it, where
// setTime(t) (each animation frame) clears and draws only the cursor's few columns of pixels.
// Clicking a row or the axis seeks there (a chunk's bar: its start); dragging along the axis
// scrubs; the wheel zooms the time axis, dragging a row pans, a double click shows the whole plan.
import { axisLabel, clock, css, escapeHtml, gapText, injectStyle, niceStep, num, stateColours } from './format.js';

const STYLE = `
.cp-gantt { position: relative; font: 12px/1.35 system-ui, -apple-system, "Segoe UI", sans-serif; color: #222;
  background: #fff; user-select: none; -webkit-user-select: none; }
.cp-gantt-head { display: flex; flex-wrap: wrap; align-items: baseline; gap: 2px 18px; padding: 4px 10px 4px; }
.cp-gantt-title { white-space: nowrap; font-size: 13px; }
.cp-gantt-title b { font-weight: 600; }
.cp-gantt-legend { display: flex; flex-wrap: wrap; align-items: center; gap: 2px 14px; color: #444; }
.cp-gantt-key { display: inline-flex; align-items: center; gap: 5px; white-space: nowrap; }
.cp-gantt-sw { display: inline-block; width: 18px; height: 11px; box-sizing: border-box; }
.cp-gantt-hint { color: #888; white-space: nowrap; }
.cp-gantt-plot { position: relative; width: 100%; cursor: crosshair; touch-action: pan-y; }
.cp-gantt-plot canvas { position: absolute; left: 0; top: 0; display: block; }
.cp-gantt-tip { position: absolute; z-index: 5; pointer-events: none; max-width: 340px; padding: 4px 7px;
  background: rgba(30, 30, 30, 0.92); color: #fff; border-radius: 4px; font-size: 12px; line-height: 1.35;
  white-space: normal; display: none; }
.cp-gantt-empty { padding: 8px 10px; color: #666; }
`;

const AXIS_H = 24; // the time axis' height under the rows, px
const TOP = 4; // room over the first row for the critical path's frames, px
const RIGHT_PAD = 14;
const GUTTER_MIN = 36;
const GUTTER_MAX = 160;
const TICK_SPACING = 96; // the least room between two axis labels, px
const MAX_BIN_PX = 40; // the wheel zooms in until one merged bin of the record (meta.gantt_resolution_s) is this wide

export function createGantt(el, meta, { onSeek } = {}) {
  injectStyle('cp-gantt-style', STYLE);
  const rows = meta.gantt || [];
  const robots = meta.robots || [];
  const n = rows.length;
  const makespan = Math.max(Number(meta.makespan) || 0, 0);
  const sched = (meta.summary && meta.summary.schedule) || {};
  const bound = meta.lower_bound ?? sched.lower_bound_s ?? null;
  const span = Math.max(makespan, bound || 0, 1e-9);
  const colours = stateColours(meta);
  const critical = new Set(meta.critical_path || []);
  const robotColour = (i) => (robots[i] && robots[i].colour) || [90, 90, 90];
  const resolution = Number(meta.gantt_resolution_s) || span / 4000;
  const seek = (t) => { if (onSeek) onSeek(Math.min(Math.max(t, 0), makespan)); };

  el.classList.add('cp-gantt');
  el.replaceChildren();
  const head = add(el, 'div', 'cp-gantt-head');
  const title = add(head, 'div', 'cp-gantt-title');
  title.innerHTML = titleHtml(makespan, bound);
  const legend = add(head, 'div', 'cp-gantt-legend');
  legend.innerHTML = legendHtml(robots, colours, rows.some((r) => (r.chunks || []).some((c) => critical.has(c[0]))),
    bound);
  if (!n) {
    add(el, 'div', 'cp-gantt-empty').textContent = 'no robots in this plan';
    return { setTime() {} };
  }
  const plot = add(el, 'div', 'cp-gantt-plot');
  const base = add(plot, 'canvas');
  const over = add(plot, 'canvas');
  const tip = add(plot, 'div', 'cp-gantt-tip');
  const bctx = base.getContext('2d');
  const octx = over.getContext('2d');

  // rows: 28 px up to 6 robots, then thinner (64 robots: 10 px), bars with a gap between rows
  const pitch = n <= 6 ? 28 : Math.max(10, Math.min(28, Math.floor(300 / n)));
  const bar = pitch - Math.max(2, Math.round(pitch * 0.22));
  const strip = Math.max(2, Math.round(bar / 4)); // the travelling strip at the bar's foot
  const lane = bar - strip - 1; // the printing above it
  const nameFont = `600 ${Math.max(8, Math.min(12, pitch - 3))}px system-ui, sans-serif`;
  const labelFont = `${Math.max(8, Math.min(11, lane - 3))}px system-ui, sans-serif`;
  const rowsBottom = TOP + n * pitch;
  const height = rowsBottom + AXIS_H;
  plot.style.height = `${height}px`;

  let width = 0; // the plot's width, CSS px
  let dpr = 1;
  let left = GUTTER_MIN;
  let right = 0;
  let v0 = 0; // the time window shown, s
  let v1 = span;
  let cursor = 0;
  let cursorPx = null; // the cursor's column as drawn (device px), null when not drawn
  let names = null; // each robot's name cut to fit the gutter

  const x = (t) => left + ((t - v0) / (v1 - v0)) * (right - left);
  const timeAt = (px) => v0 + ((px - left) / (right - left)) * (v1 - v0);
  const rowTop = (i) => TOP + i * pitch + (pitch - bar) / 2;

  function layout() {
    width = plot.clientWidth;
    dpr = window.devicePixelRatio || 1;
    if (!width) return false;
    bctx.font = nameFont;
    const widest = Math.max(...rows.map((r) => bctx.measureText(String(r.name)).width));
    left = Math.round(Math.min(GUTTER_MAX, Math.max(GUTTER_MIN, widest + 16)));
    right = Math.max(left + 10, width - RIGHT_PAD);
    names = rows.map((r) => fit(bctx, String(r.name), left - 12));
    for (const c of [base, over]) {
      c.width = Math.round(width * dpr);
      c.height = Math.round(height * dpr);
      c.style.width = `${width}px`;
      c.style.height = `${height}px`;
    }
    return true;
  }

  function draw() {
    if (!width) return;
    const g = bctx;
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, width, height);
    for (let i = 0; i < n; i++) { // row bands and names
      if (i % 2) {
        g.fillStyle = '#f5f6f8';
        g.fillRect(0, TOP + i * pitch, width, pitch);
      }
      g.font = nameFont;
      g.textBaseline = 'middle';
      g.textAlign = 'left';
      g.fillStyle = css(robotColour(i));
      g.fillText(names[i], 8, rowTop(i) + bar / 2);
    }
    g.save();
    g.beginPath();
    g.rect(left - 4, 0, right - left + 8, rowsBottom);
    g.clip();
    const tol = (v1 - v0) / (right - left); // a px in s: bars narrower are drawn 1 px wide
    for (let i = 0; i < n; i++) {
      const row = rows[i];
      const y0 = rowTop(i);
      bars(g, row.print, y0, lane, css(robotColour(i)), tol);
      travel(g, row, y0, tol);
      bars(g, row.wait, y0, bar, css(colours.waiting), tol);
      chunks(g, row.chunks || [], y0);
    }
    g.restore();
    if (bound && bound >= v0 && bound <= v1) { // the lower bound, dashed
      const xb = Math.round(x(bound)) + 0.5;
      g.save();
      g.strokeStyle = css(colours.bound);
      g.lineWidth = 1.5;
      g.setLineDash([5, 4]);
      g.beginPath();
      g.moveTo(xb, 0);
      g.lineTo(xb, rowsBottom + 4);
      g.stroke();
      g.restore();
    }
    axis(g);
    drawCursor(true);
  }

  // intervals [a, b, ...] as bars from y0, h tall, in one colour; those outside the window skipped
  function bars(g, list, y0, h, colour, tol) {
    if (!list || !list.length) return;
    g.fillStyle = colour;
    g.beginPath();
    for (const iv of list) {
      const a = iv[0];
      const b = iv[1];
      if (b < v0 - tol || a > v1 + tol) continue;
      const xa = x(a);
      const xb = Math.max(x(b), xa + 1);
      g.rect(xa, y0, xb - xa, h);
    }
    g.fill();
  }

  // the travelling strip under the printing, as the PNG chart's: where the robot travels (the
  // merged intervals), each piece as tall as the share of travel in its share bin (at least
  // 1 px: a short drive between long prints still shows)
  function travel(g, row, y0, tol) {
    const sh = row.share;
    const list = row.travel || [];
    const bottom = y0 + bar;
    if (!sh || !sh.bin_s || !sh.travel || !sh.travel.length) {
      bars(g, list, bottom - strip, strip, css(colours.travelling), tol);
      return;
    }
    const last = sh.travel.length - 1;
    const byHeight = Array.from({ length: strip + 1 }, () => []);
    for (const [a, b] of list) {
      if (b < v0 - tol || a > v1 + tol) continue;
      const ka = Math.min(last, Math.max(0, Math.floor(a / sh.bin_s)));
      const kb = Math.min(last, Math.max(ka, Math.floor(b / sh.bin_s)));
      for (let k = ka; k <= kb; k++) {
        const h = Math.max(1, Math.min(strip, Math.ceil((sh.travel[k] / 100) * strip - 1e-9)));
        byHeight[h].push(Math.max(a, k * sh.bin_s), Math.min(b, (k + 1) * sh.bin_s));
      }
    }
    g.fillStyle = css(colours.travelling);
    g.beginPath();
    byHeight.forEach((ends, h) => {
      for (let m = 0; m < ends.length; m += 2) {
        const xa = x(ends[m]);
        g.rect(xa, bottom - h, Math.max(x(ends[m + 1]) - xa, 1), h);
      }
    });
    g.fill();
  }

  // each chunk's id on its bar (on the part in view) where it fits; the critical path's framed
  function chunks(g, list, y0) {
    g.font = labelFont;
    g.textAlign = 'center';
    g.textBaseline = 'middle';
    for (const [id, a, b] of list) {
      if (b < v0 || a > v1) continue;
      const xa = x(a);
      const xb = Math.max(x(b), xa + 2);
      if (critical.has(id)) { // around the bar and its strip, a white line apart from a red robot's bar
        g.lineWidth = 2;
        g.strokeStyle = css(colours.critical);
        g.strokeRect(xa - 2.5, y0 - 2.5, xb - xa + 5, bar + 5);
        g.lineWidth = 1;
        g.strokeStyle = '#fff';
        g.strokeRect(xa - 1, y0 - 1, xb - xa + 2, bar + 2);
      }
      const va = Math.max(xa, left);
      const vb = Math.min(xb, right);
      if (lane < 9) continue;
      const w = g.measureText(id).width;
      if (vb - va < w + 8) continue;
      g.save();
      g.shadowColor = 'rgba(0, 0, 0, 0.45)';
      g.shadowBlur = 2;
      g.fillStyle = '#fff';
      g.fillText(id, (va + vb) / 2, y0 + lane / 2 + 0.5);
      g.restore();
    }
  }

  function axis(g) {
    const y = rowsBottom + 0.5;
    g.strokeStyle = '#555';
    g.lineWidth = 1;
    g.beginPath();
    g.moveTo(left, y);
    g.lineTo(right, y);
    const step = niceStep(((v1 - v0) * TICK_SPACING) / Math.max(right - left, 1));
    const ticks = [];
    for (let k = Math.ceil(v0 / step - 1e-9); k * step <= v1 + 1e-9; k++) ticks.push(k * step);
    for (const t of ticks) {
      const xt = Math.round(x(t)) + 0.5;
      g.moveTo(xt, y);
      g.lineTo(xt, y + 5);
    }
    g.stroke();
    g.fillStyle = '#444';
    g.font = '11px system-ui, sans-serif';
    g.textBaseline = 'top';
    for (const t of ticks) {
      const label = axisLabel(t, step, span);
      const w = g.measureText(label).width;
      const xt = Math.min(Math.max(x(t) - w / 2, 2), width - w - 2);
      g.textAlign = 'left';
      g.fillText(label, xt, y + 7);
    }
  }

  // the time cursor: only the columns it leaves and the ones it moves to are redrawn
  function drawCursor(force) {
    if (!width) return;
    const t = Math.min(Math.max(cursor, 0), span);
    const px = Math.round(x(t) * dpr);
    if (!force && px === cursorPx) return;
    const o = octx;
    o.setTransform(1, 0, 0, 1, 0, 0);
    if (force) o.clearRect(0, 0, over.width, over.height);
    else if (cursorPx !== null) o.clearRect(cursorPx - 8 * dpr, 0, 16 * dpr, over.height);
    cursorPx = null;
    if (t < v0 || t > v1) return;
    cursorPx = px;
    const bottom = rowsBottom * dpr;
    o.fillStyle = 'rgba(255, 255, 255, 0.85)';
    o.fillRect(px - 2 * dpr, 0, 4 * dpr, bottom);
    o.fillStyle = '#111';
    o.fillRect(px - dpr, 0, 2 * dpr, bottom);
    o.beginPath(); // a pointer on the axis
    o.moveTo(px, bottom);
    o.lineTo(px - 5 * dpr, bottom + 7 * dpr);
    o.lineTo(px + 5 * dpr, bottom + 7 * dpr);
    o.closePath();
    o.fill();
  }

  // what is under the mouse at (mx, my) px in the plot: a chunk's bar, a wait, a row or the axis
  function hit(mx, my) {
    if (mx < left - 4 || mx > right + 4) return null;
    const t = timeAt(mx);
    if (my >= rowsBottom) return { kind: 'axis', t };
    const i = Math.min(n - 1, Math.max(0, Math.floor((my - TOP) / pitch)));
    const row = rows[i];
    const y0 = rowTop(i);
    const tol = (3 * (v1 - v0)) / (right - left);
    if (my >= y0 - 2 && my <= y0 + bar + 2) {
      const w = (row.wait || []).find((iv) => t >= iv[0] - tol && t <= iv[1] + tol);
      if (w) return { kind: 'wait', i, t, wait: w };
      const c = (row.chunks || []).find((iv) => t >= iv[1] - tol && t <= iv[2] + tol);
      if (c) return { kind: 'chunk', i, t, chunk: c };
    }
    return { kind: 'row', i, t };
  }

  function tipHtml(h) {
    const name = escapeHtml(rows[h.i] ? rows[h.i].name : '');
    if (h.kind === 'axis') return `${clock(Math.max(h.t, 0))} <span style="opacity:.7">· click: jump there</span>`;
    if (h.kind === 'wait') {
      const [a, b, ev] = h.wait;
      return `<b>robot ${name} waits</b> for ${escapeHtml(ev || '?')}<br>${clock(a)} → ${clock(b)} (${clock(b - a)})`;
    }
    if (h.kind === 'chunk') {
      const [id, a, b] = h.chunk;
      return `<b>chunk ${escapeHtml(id)}</b>${critical.has(id) ? ' · on the critical path' : ''}<br>robot ${name} prints it `
        + `${clock(a)} → ${clock(b)} (${clock(b - a)})<br><span style="opacity:.7">click: jump to its start</span>`;
    }
    return `robot ${name} ${activity(rows[h.i], h.t)}`;
  }

  // what a robot does in the record's share bin around t: "3:00:00–3:00:17: printing 95%, ..."
  function activity(row, t) {
    const sh = row.share;
    if (!sh || !sh.bin_s || !sh.print || !sh.print.length) return `at ${clock(t)}`;
    const k = Math.min(sh.print.length - 1, Math.max(0, Math.floor(t / sh.bin_s)));
    const a = k * sh.bin_s;
    const b = a + sh.bin_s;
    let wait = 0;
    for (const [wa, wb] of row.wait || []) wait += Math.max(0, Math.min(b, wb) - Math.max(a, wa));
    const p = sh.print[k];
    const tr = sh.travel[k];
    const w = Math.round((100 * wait) / sh.bin_s);
    const idle = Math.max(0, 100 - p - tr - w);
    const parts = [['printing', p], ['travelling', tr], ['waiting', w], ['idle', idle]]
      .filter(([, v]) => v > 0).map(([k2, v]) => `${k2} ${v}%`);
    return `${clock(a)}–${clock(b)}: ${parts.join(', ') || 'idle'}`;
  }

  function showTip(h, mx, my) {
    if (!h) { tip.style.display = 'none'; return; }
    tip.innerHTML = tipHtml(h);
    tip.style.display = 'block';
    const w = tip.offsetWidth;
    const th = tip.offsetHeight;
    tip.style.left = `${Math.max(0, Math.min(mx + 12, width - w - 2))}px`;
    tip.style.top = `${my + 16 + th > height ? Math.max(0, my - th - 8) : my + 16}px`;
  }

  function zoomTo(a, b) {
    // zoomed in at most until one of the record's merged bins is MAX_BIN_PX wide
    const least = Math.min(span, Math.max(0.5, (resolution * (right - left)) / MAX_BIN_PX));
    let w = Math.min(span, Math.max(b - a, least));
    a = Math.min(Math.max(a, 0), span - w);
    if (w >= span) { a = 0; w = span; }
    if (a === v0 && a + w === v1) return false;
    v0 = a;
    v1 = a + w;
    tip.style.display = 'none';
    draw();
    return true;
  }

  const local = (e) => {
    const r = plot.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  };
  let press = null; // the pointer pressed: where, what under it, and whether it moved (pan or scrub)
  plot.addEventListener('pointerdown', (e) => {
    if (e.button !== 0) return;
    const [mx, my] = local(e);
    const h = hit(mx, my);
    if (!h) return;
    press = { mx, v0, v1, h, moved: false, scrub: h.kind === 'axis' };
    plot.setPointerCapture(e.pointerId);
    if (press.scrub) seek(h.t);
  });
  plot.addEventListener('pointermove', (e) => {
    const [mx, my] = local(e);
    if (press) {
      if (Math.abs(mx - press.mx) > 4) press.moved = true;
      if (press.scrub) seek(timeAt(Math.min(Math.max(mx, left), right)));
      else if (press.moved && press.v1 - press.v0 < span) {
        const dt = ((mx - press.mx) / (right - left)) * (press.v1 - press.v0);
        zoomTo(press.v0 - dt, press.v1 - dt);
      }
      tip.style.display = 'none';
      return;
    }
    showTip(hit(mx, my), mx, my);
  });
  plot.addEventListener('pointerup', (e) => {
    if (!press) return;
    const p = press;
    press = null;
    if (plot.hasPointerCapture(e.pointerId)) plot.releasePointerCapture(e.pointerId);
    if (p.scrub || p.moved) return;
    seek(p.h.kind === 'chunk' ? p.h.chunk[1] : p.h.t);
  });
  plot.addEventListener('pointercancel', () => { press = null; });
  plot.addEventListener('pointerleave', () => { tip.style.display = 'none'; });
  plot.addEventListener('dblclick', () => zoomTo(0, span));
  plot.addEventListener('wheel', (e) => {
    const [mx] = local(e);
    if (mx < left || mx > right) return;
    const f = Math.exp(Math.max(-1, Math.min(1, e.deltaY * (e.deltaMode ? 0.05 : 0.002))));
    const t = timeAt(mx);
    const w = (v1 - v0) * f;
    const a = t - ((mx - left) / (right - left)) * w;
    if (zoomTo(a, a + w)) e.preventDefault();
  }, { passive: false });

  const redraw = () => { if (layout()) draw(); };
  new ResizeObserver(() => {
    if (plot.clientWidth !== width || (window.devicePixelRatio || 1) !== dpr) redraw();
  }).observe(plot);
  window.addEventListener('resize', () => { if ((window.devicePixelRatio || 1) !== dpr) redraw(); });
  redraw();

  return {
    setTime(t) {
      cursor = Number(t) || 0;
      drawCursor(false);
    },
  };
}

function add(parent, tag, cls) {
  const e = document.createElement(tag);
  if (cls) e.className = cls;
  parent.appendChild(e);
  return e;
}

// the text cut (with an ellipsis) to at most `room` px in the context's font
function fit(g, text, room) {
  if (g.measureText(text).width <= room) return text;
  let s = text;
  while (s.length > 1 && g.measureText(`${s}…`).width > room) s = s.slice(0, -1);
  return `${s}…`;
}

function titleHtml(makespan, bound) {
  let s = `makespan <b>${clock(makespan)}</b> (${num(makespan)} s)`;
  if (bound) {
    s += ` &nbsp;·&nbsp; lower bound ${clock(bound)} (makespan ${gapText(makespan, bound)})`;
  }
  return s;
}

function legendHtml(robots, colours, anyCritical, bound) {
  const cols = robots.slice(0, 4).map((r) => css(r.colour || [90, 90, 90]));
  const stops = cols.length ? cols.map((c, k) => `${c} ${(100 * k) / cols.length}% ${(100 * (k + 1)) / cols.length}%`)
    .join(', ') : '#888 0 100%';
  const keys = [
    `<i class="cp-gantt-sw" style="background: linear-gradient(90deg, ${stops})"></i>printing (robot's colour)`,
    `<i class="cp-gantt-sw" style="background: linear-gradient(transparent 60%, ${css(colours.travelling)} 60%)"></i>travelling (strip: share of the time)`,
    `<i class="cp-gantt-sw" style="background: ${css(colours.waiting)}"></i>waiting`,
  ];
  if (anyCritical) keys.push(`<i class="cp-gantt-sw" style="border: 2px solid ${css(colours.critical)}"></i>critical path`);
  if (bound) keys.push(`<i class="cp-gantt-sw" style="width: 2px; margin: 0 8px; background: repeating-linear-gradient(${css(colours.bound)} 0 3px, transparent 3px 5px)"></i>lower bound`);
  return keys.map((k) => `<span class="cp-gantt-key">${k}</span>`).join('')
    + '<span class="cp-gantt-hint">wheel: zoom · drag: pan · double-click: all</span>';
}
