// The page's layout: a bar of controls, the 3D view with the Gantt chart under it, a side panel
// (legend, summary, findings). The element ids are the page's contract (docs/viewer.md).

import { MODES } from './colours.js';

const CSS = `
* { box-sizing: border-box; }
html, body { margin: 0; height: 100%; font: 13px/1.35 system-ui, -apple-system, "Segoe UI", sans-serif; color: #222; background: #f4f4f4; }
#app { display: grid; grid-template-columns: 1fr 340px; grid-template-rows: auto 1fr auto; height: 100vh; }
#bar { grid-column: 1 / 3; display: flex; flex-wrap: wrap; gap: 6px 12px; align-items: center; padding: 6px 10px; background: #fff; border-bottom: 1px solid #ddd; }
#bar .group { display: flex; align-items: center; gap: 4px; }
#bar h1 { font-size: 14px; margin: 0 8px 0 0; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; max-width: 260px; }
#time-slider { width: min(36vw, 520px); }
#clock { font-variant-numeric: tabular-nums; min-width: 150px; }
#main { position: relative; min-height: 200px; }
#view { position: absolute; inset: 0; background: #fff; }
#view canvas { display: block; }
#grid-label { position: absolute; left: 8px; bottom: 6px; color: #555; background: rgba(255,255,255,.8); padding: 1px 4px; pointer-events: none; }
#notice { position: absolute; left: 8px; top: 8px; right: 230px; background: #fff6d5; border: 1px solid #e0c060; padding: 4px 28px 4px 8px; pointer-events: none; }
#notice-close { position: absolute; right: 3px; top: 2px; pointer-events: auto; border: none; background: none; font-size: 15px; line-height: 1; padding: 2px 5px; cursor: pointer; color: #6a5a20; }
#notice-close:hover { color: #000; }
#status { display: grid; grid-template-columns: fit-content(9em) minmax(0, 1fr) auto; gap: 2px 8px; align-items: baseline; padding: 0 2px; font-variant-numeric: tabular-nums; }
.status-row { display: contents; }
.status-name { font-weight: 600; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
.status-state { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; color: #444; }
.status-done { color: #666; font-size: 11.5px; white-space: nowrap; }
button:disabled, option:disabled { cursor: not-allowed; }
#views { position: absolute; right: 8px; top: 8px; display: flex; gap: 4px; }
#side { grid-row: 2 / 4; grid-column: 2; overflow: auto; background: #fff; border-left: 1px solid #ddd; padding: 8px; }
#side h2 { font-size: 13px; margin: 10px 0 4px; }
#gantt { grid-column: 1; min-height: 120px; max-height: 34vh; overflow: auto; background: #fff; border-top: 1px solid #ddd; }
.legend-row { display: flex; align-items: center; gap: 6px; }
.swatch { display: inline-block; width: 18px; height: 10px; border-radius: 2px; }
button, select { font: inherit; }
details.about pre { white-space: pre-wrap; font-size: 11px; }
`;

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'text') e.textContent = v; else e.setAttribute(k, v);
  }
  e.append(...children);
  return e;
}

export function layout(body, meta, speeds) {
  document.head.appendChild(el('style', { text: CSS }));
  const play = el('button', { id: 'play', type: 'button', 'aria-pressed': 'false', text: 'play' });
  const speed = el('select', { id: 'speed', title: 'playback speed over real print time' },
                   ...speeds.map((s) => el('option', { value: String(s), text: `${s.toLocaleString('en')}x` })));
  const slider = el('input', { id: 'time-slider', type: 'range', min: '0', max: String(meta.makespan || 0), step: 'any',
                                value: String(meta.makespan || 0), title: 'time (real print time)' });
  const clockEl = el('span', { id: 'clock' });
  const prev = el('button', { id: 'prev-event', type: 'button', title: 'previous NOTIFY / WAIT', text: '|<' });
  const next = el('button', { id: 'next-event', type: 'button', title: 'next NOTIFY / WAIT', text: '>|' });
  const mode = el('select', { id: 'colour-mode', title: 'colour the material' },
                  ...MODES.map(([m, label]) => el('option', { value: m, text: label })));
  const layerLo = el('input', { id: 'layer-lo', type: 'range', title: 'lowest height shown' });
  const layerHi = el('input', { id: 'layer-hi', type: 'range', title: 'highest height shown' });
  const layerLabel = el('span', { class: 'layers' });
  const travel = el('input', { id: 'travel', type: 'checkbox' });
  travel.checked = false;
  const outlines = el('input', { id: 'chunk-outlines', type: 'checkbox' });
  const reset = el('button', { id: 'view-reset', type: 'button', text: 'reset' });
  const top = el('button', { id: 'view-top', type: 'button', text: 'top' });
  const front = el('button', { id: 'view-front', type: 'button', text: 'front' });
  const side = el('button', { id: 'view-side', type: 'button', text: 'side' });
  const view = el('div', { id: 'view' });
  const noticeText = el('span', { id: 'notice-text' });
  const noticeClose = el('button', { id: 'notice-close', type: 'button', title: 'close this notice', 'aria-label': 'close', text: '\u00d7' });
  const notice = el('div', { id: 'notice', role: 'status' }, noticeText, noticeClose);
  noticeClose.addEventListener('click', () => { notice.hidden = true; });
  notice.hidden = true;
  const gridLabel = el('div', { id: 'grid-label' });
  const legend = el('div', { id: 'legend' });
  const status = el('div', { id: 'status' });
  const summary = el('div', { id: 'summary' });
  const findings = el('div', { id: 'findings' });
  const gantt = el('div', { id: 'gantt' });
  const licence = document.getElementById('cooprint-licence');
  const about = el('details', { class: 'about' }, el('summary', { text: 'about this page' }),
    el('p', { text: 'cooprint\'s plan viewer: one file, no network. The material is drawn as laid down by the time shown; '
                    + 'nearly collinear segments are merged within a display tolerance (' + (meta.geometry.tolerance || 0).toFixed(3)
                    + ' mm). Drawn with three.js, under its licence:' }),
    el('pre', { text: licence ? licence.textContent : '' }));
  const bar = el('div', { id: 'bar' },
    el('h1', { text: meta.title || 'plan', title: meta.source || '' }),
    el('span', { class: 'group' }, play, speed, prev, next),
    el('span', { class: 'group' }, slider, clockEl),
    el('label', { class: 'group' }, 'colour ', mode),
    el('span', { class: 'group', title: 'look inside: the heights shown' }, 'z ', layerLo, layerHi, layerLabel),
    el('label', { class: 'group' }, travel, 'travel'),
    el('label', { class: 'group' }, outlines, 'chunk outlines'));
  const main = el('div', { id: 'main' }, view, el('div', { id: 'views' }, reset, top, front, side), gridLabel, notice);
  const sidePanel = el('div', { id: 'side' }, el('h2', { text: 'legend' }), legend,
                       el('h2', { text: 'robots at this time' }), status, el('h2', { text: 'summary' }), summary,
                       el('h2', { text: 'findings' }), findings, about);
  body.appendChild(el('div', { id: 'app' }, bar, main, sidePanel, gantt));
  return {
    play, speed, slider, clock: clockEl, prev, next, mode, layerLo, layerHi, layerLabel, travel, outlines, reset, top,
    front, side, view, notice, gridLabel, legend, status, summary, findings, gantt,
    // Shows `text` in #notice (closed by its × button; shown again by the next notice).
    showNotice(text) { noticeText.textContent = text; notice.hidden = false; },
    setLayerRange(lo, top, stepMm) {
      const step = Math.max(stepMm, 0.01);
      const hi = lo + Math.ceil((top - lo) / step - 1e-9) * step; // a value the slider can hold
      for (const s of [layerLo, layerHi]) {
        s.min = String(lo); s.max = String(hi); s.step = String(step);
      }
      layerLo.value = String(lo);
      layerHi.value = String(hi);
      layerLabel.textContent = `z ${lo.toFixed(1)} - ${hi.toFixed(1)} mm`;
    },
  };
}
