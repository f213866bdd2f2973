// Small helpers shared by the panels (gantt.js, panels.js): times written as clocks, colours
// from the page's record, and each module's own style sheet put into the page once.

const DAY = 86400;

// A time in s as a clock: "h:mm:ss" under a day, "N d hh:mm:ss" from a day on (a 375-day plan
// reads "375 d 04:00:00", not "9004:00:00"; as the PNG pictures write it; a no-break space in "N d", so that a narrow
// table breaks a clock only before its hours); null or not a number: "–".
export function clock(t) {
  if (t == null || !Number.isFinite(t)) return '–';
  const sign = t < 0 ? '-' : '';
  let s = Math.round(Math.abs(t));
  const d = Math.floor(s / DAY);
  s -= d * DAY;
  const h = Math.floor(s / 3600);
  const m = Math.floor((s % 3600) / 60);
  const sec = s % 60;
  const mmss = `${String(m).padStart(2, '0')}:${String(sec).padStart(2, '0')}`;
  return d ? `${sign}${d}\u00a0d ${String(h).padStart(2, '0')}:${mmss}` : `${sign}${h}:${mmss}`;
}

// The time axis' label of tick t (s) for ticks `step` s apart on a plan of `span` s: "h:mm"
// ("1 d 04:00" when the plan lasts a day or more), with ":ss" when the ticks are under a minute
// apart; under ten seconds apart, tenths of a second too.
export function axisLabel(t, step, span) {
  const days = span >= DAY;
  const whole = Math.floor(t + 1e-6);
  const d = Math.floor(whole / DAY);
  const r = whole - d * DAY;
  const h = Math.floor(r / 3600);
  const m = Math.floor((r % 3600) / 60);
  let out = days ? `${d} d ${String(h).padStart(2, '0')}:${String(m).padStart(2, '0')}`
    : `${h}:${String(m).padStart(2, '0')}`;
  if (step < 60) out += `:${String(r % 60).padStart(2, '0')}`;
  if (step < 1) out += `.${Math.round((t - whole) * 10) % 10}`;
  return out;
}

const STEPS = [0.1, 0.2, 0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800,
  21600, 43200, DAY, 2 * DAY, 7 * DAY, 14 * DAY, 28 * DAY];

// The least round tick step (s) of at least `raw` s: seconds, minutes, hours, days, weeks.
export function niceStep(raw) {
  for (const s of STEPS) if (s >= raw) return s;
  return 28 * DAY * Math.ceil(raw / (28 * DAY));
}

// A colour [r, g, b] (0-255) as CSS, with an optional alpha.
export function css(rgb, alpha = 1) {
  const [r, g, b] = rgb;
  return alpha >= 1 ? `rgb(${r}, ${g}, ${b})` : `rgba(${r}, ${g}, ${b}, ${alpha})`;
}

// Text made safe to put into HTML.
export function escapeHtml(s) {
  return String(s).replace(/[&<>"']/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' }[c]));
}

// A number with thin spaces between thousands ("16 682"), `digits` decimals.
export function num(x, digits = 0) {
  if (x == null || !Number.isFinite(x)) return '–';
  const [i, f] = Math.abs(x).toFixed(digits).split('.');
  return (x < 0 ? '-' : '') + i.replace(/\B(?=(\d{3})+(?!\d))/g, '\u2009') + (f ? `.${f}` : '');
}

// A share (0-1) as a percentage: "95.0%", "0.4%", "0%".
export function percent(x) {
  if (!Number.isFinite(x) || x <= 0) return '0%';
  if (x < 0.0001) return '<0.01%';
  return `${(100 * x).toFixed(x < 0.001 ? 2 : 1)}%`;
}

// How far the makespan is over the lower bound: "+0.3%", "+0.013%" (three decimals under 0.1%).
export function gapText(makespan, bound) {
  const gap = makespan / bound - 1;
  return `${gap >= 0 ? '+' : ''}${(100 * gap).toFixed(gap !== 0 && Math.abs(gap) < 0.001 ? 3 : 1)}%`;
}

// Puts the style sheet `text` into the page once (a <style id=`id`>), so that the page itself
// needs no rules for the panels.
export function injectStyle(id, text) {
  if (document.getElementById(id)) return;
  const el = document.createElement('style');
  el.id = id;
  el.textContent = text;
  document.head.appendChild(el);
}

// The fleet's robot colours by name, from the page's record (meta.robots[i].colour).
export function robotColours(meta) {
  const out = new Map();
  (meta.robots || []).forEach((r) => out.set(r.name, r.colour || [90, 90, 90]));
  return out;
}

// The Gantt chart's state colours from the record (meta.colours, the PNG chart's), with the
// same defaults when a record has none.
export function stateColours(meta) {
  const c = meta.colours || {};
  return {
    travelling: c.travelling || [185, 185, 185],
    waiting: c.waiting || [235, 200, 60],
    critical: c.critical || [204, 0, 0],
    bound: c.bound || [40, 40, 40],
  };
}
