// The side panels:
//   createSummary(el, meta) -> {}
//   createFindings(el, meta, {onSelect(finding, index)}) -> {select(index)}
// meta: the page's JSON record (render/viewer/meta.py). The summary: the makespan (and the lower
// bound, the planned makespan), per robot its printing, travelling, waiting and idle time (and
// each as a share of the makespan, also drawn as a bar), its material, the findings counted by
// kind. The findings: one item per meta.findings entry (data-index = its index), its severity's
// colour, kind, robot, time, chunk, count and detail; a click selects it (highlighted, onSelect).
// A long list shows PAGE items at a time (buttons show the next or the earlier ones; selecting a
// finding elsewhere shows its page), so that 10,000 findings cost what 500 do.
import { clock, css, escapeHtml, gapText, injectStyle, num, percent, robotColours, stateColours } from './format.js';

const STYLE = `
.cp-summary, .cp-findings { font: 12px/1.4 system-ui, -apple-system, "Segoe UI", sans-serif; color: #222; }
.cp-summary { padding: 6px 4px; }
.cp-sum-makespan { font-size: 14px; }
.cp-sum-makespan b { font-weight: 600; }
.cp-sum-line { color: #555; }
.cp-sum-table { overflow-x: auto; }
.cp-sum-robots { border-collapse: collapse; margin: 6px 0 4px; width: 100%; font-variant-numeric: tabular-nums; font-size: 11.5px; }
.cp-sum-robots th { font-weight: 500; color: #666; text-align: right; padding: 1px 3px; white-space: nowrap; }
.cp-sum-robots th:first-child, .cp-sum-robots td:first-child { text-align: left; }
/* a clock of days breaks before its hours ("2 d" over "06:01:50"), so that the table fits the panel */
.cp-sum-robots td { text-align: right; padding: 1px 3px; vertical-align: top; }
.cp-sum-robots td:last-child { white-space: nowrap; }
.cp-sum-robots td small { display: block; color: #777; font-size: 10.5px; line-height: 1.1; }
.cp-sum-robots tr.cp-sum-bar td { padding: 0 4px 4px; }
.cp-sum-robots tfoot td { border-top: 1px solid #ddd; color: #444; }
.cp-sum-name { font-weight: 600; max-width: 4.5em; overflow: hidden; text-overflow: ellipsis; white-space: nowrap; }
.cp-share { display: flex; height: 5px; border-radius: 2px; overflow: hidden; background: #eee; }
.cp-share i { display: block; height: 100%; }
.cp-sum-counts { margin-top: 4px; display: flex; flex-wrap: wrap; gap: 3px 6px; align-items: center; }
.cp-badge { display: inline-block; padding: 0 6px; border-radius: 9px; color: #fff; font-size: 11px; line-height: 17px; }
.cp-sev-error { background: #c62828; }
.cp-sev-warning { background: #d98b00; }
.cp-sum-ok { color: #2e7d32; }
.cp-sum-notes { margin: 4px 0 0; padding-left: 16px; color: #555; }
.cp-findings-head { padding: 4px 10px; color: #444; font-weight: 600; }
.cp-findings-list { display: flex; flex-direction: column; }
.cp-finding { position: relative; padding: 4px 8px 4px 14px; border-bottom: 1px solid #eee; cursor: pointer; outline: none;
  content-visibility: auto; contain-intrinsic-size: auto 44px; }
.cp-finding::before { content: ""; position: absolute; left: 4px; top: 5px; bottom: 5px; width: 4px; border-radius: 2px;
  background: var(--cp-sev); }
.cp-finding:hover { background: #f4f6fa; }
.cp-finding:focus-visible { box-shadow: inset 0 0 0 2px #7aa7e0; }
.cp-finding.cp-selected { background: #fff4cf; box-shadow: inset 0 0 0 1px #e0b84a; }
.cp-f-top { display: flex; flex-wrap: wrap; gap: 0 8px; align-items: baseline; }
.cp-f-kind { font-weight: 600; }
.cp-f-robot { font-weight: 600; }
.cp-f-time, .cp-f-chunk, .cp-f-count { color: #555; font-variant-numeric: tabular-nums; }
.cp-f-detail { color: #666; font-size: 11.5px; }
.cp-findings-more { padding: 6px 10px; color: #555; display: flex; gap: 8px; align-items: center; }
.cp-findings-more button { font: inherit; padding: 1px 8px; cursor: pointer; }
.cp-findings-more:empty { display: none; }
.cp-findings-empty { padding: 6px 10px; color: #2e7d32; }
`;

const SEVERITY = { error: '#c62828', warning: '#d98b00' };
const PAGE = 500; // findings shown at first, and added by each "show more"

// The severity of a finding (its own, else its kind's in meta.summary.severity), 'error' or 'warning'.
function severityOf(meta, f) {
  const sev = f.severity || (meta.summary && meta.summary.severity && meta.summary.severity[f.kind]);
  return sev === 'warning' ? 'warning' : 'error';
}

export function createSummary(el, meta) {
  injectStyle('cp-panels-style', STYLE);
  const s = meta.summary || {};
  const makespan = Number(meta.makespan ?? s.makespan_s) || 0;
  const sched = s.schedule || {};
  const bound = meta.lower_bound ?? sched.lower_bound_s ?? null;
  const colours = robotColours(meta);
  const state = stateColours(meta);
  const parts = [];
  parts.push(`<div class="cp-sum-makespan">makespan <b>${clock(makespan)}</b> <span class="cp-sum-line">(${num(makespan)} s)</span></div>`);
  if (bound) {
    parts.push(`<div class="cp-sum-line">lower bound ${clock(bound)} (${num(bound)} s): makespan `
      + `${gapText(makespan, bound)} over it</div>`);
  }
  if (sched.planned_makespan_s != null) {
    parts.push(`<div class="cp-sum-line">planned makespan ${clock(sched.planned_makespan_s)} (scheduler's estimate)</div>`);
  }
  if (s.time_model) parts.push(`<div class="cp-sum-line">time model: ${escapeHtml(s.time_model)}</div>`);

  const robots = s.robots || [];
  if (robots.length) {
    const keys = [['printing', 'print'], ['travelling', 'travel'], ['waiting', 'wait'], ['idle', 'idle']];
    const barColour = {
      travelling: css(state.travelling), waiting: css(state.waiting), idle: '#e6e6e6',
    };
    let rowsHtml = '';
    let material = 0;
    for (const r of robots) {
      const colour = css(colours.get(r.name) || [90, 90, 90]);
      const share = r.share || {};
      const cells = keys.map(([k]) => {
        const v = Number(r[`${k}_s`]) || 0;
        const f = share[k] ?? (makespan > 0 ? v / makespan : 0);
        return `<td title="${num(v, 1)} s">${clock(v)}<small>${percent(f)}</small></td>`;
      }).join('');
      const mm3 = Number(r.material_mm3) || 0;
      material += mm3;
      rowsHtml += `<tr><td class="cp-sum-name" style="color:${colour}" title="robot ${escapeHtml(r.name)}">${escapeHtml(r.name)}</td>${cells}`
        + `<td>${num(mm3 / 1000, 1)}</td></tr>`;
      const seg = keys.map(([k]) => {
        const f = Math.max(0, Math.min(1, share[k] ?? (makespan > 0 ? (Number(r[`${k}_s`]) || 0) / makespan : 0)));
        const c = k === 'printing' ? colour : barColour[k];
        return f > 0 ? `<i style="width:${(100 * f).toFixed(2)}%;background:${c}" title="${k} ${percent(f)}"></i>` : '';
      }).join('');
      rowsHtml += `<tr class="cp-sum-bar"><td colspan="6"><div class="cp-share">${seg}</div></td></tr>`;
    }
    parts.push(`<div class="cp-sum-table"><table class="cp-sum-robots"><thead><tr><th>robot</th>${keys.map(([, h]) => `<th>${h}</th>`).join('')}`
      + `<th>cm³</th></tr></thead><tbody>${rowsHtml}</tbody>`
      + (robots.length > 1 ? `<tfoot><tr><td>all</td><td colspan="4"></td><td>${num(material / 1000, 1)}</td></tr></tfoot>` : '')
      + '</table></div>');
  }

  const counts = s.finding_counts || {};
  const checked = s.checked || [];
  const nonzero = Object.entries(counts).filter(([, c]) => c > 0);
  if (nonzero.length) {
    const badges = nonzero.map(([k, c]) => {
      const sev = severityOf(meta, { kind: k });
      return `<span class="cp-badge cp-sev-${sev}" title="${sev}">${escapeHtml(k)} ${num(c)}</span>`;
    }).join('');
    parts.push(`<div class="cp-sum-counts">findings: ${badges}</div>`);
  } else if (checked.length) {
    parts.push(`<div class="cp-sum-counts cp-sum-ok">no findings (${checked.length} checks run)</div>`);
  } else {
    parts.push('<div class="cp-sum-counts cp-sum-line">no checks were run</div>');
  }
  if ((s.notes || []).length) {
    parts.push(`<ul class="cp-sum-notes">${s.notes.map((t) => `<li>${escapeHtml(t)}</li>`).join('')}</ul>`);
  }
  el.classList.add('cp-summary');
  el.innerHTML = parts.join('');
  return {};
}

export function createFindings(el, meta, { onSelect } = {}) {
  injectStyle('cp-panels-style', STYLE);
  const findings = meta.findings || [];
  const colours = robotColours(meta);
  el.classList.add('cp-findings');
  el.replaceChildren();
  if (!findings.length) {
    const checked = (meta.summary && meta.summary.checked) || [];
    const empty = document.createElement('div');
    empty.className = 'cp-findings-empty';
    empty.textContent = checked.length ? 'no findings' : 'no findings (no checks were run)';
    el.appendChild(empty);
    return { select() {} };
  }
  const errors = findings.filter((f) => severityOf(meta, f) === 'error').length;
  const head = document.createElement('div');
  head.className = 'cp-findings-head';
  head.textContent = `${num(findings.length)} finding${findings.length === 1 ? '' : 's'}`
    + ` (${num(errors)} error${errors === 1 ? '' : 's'}, ${num(findings.length - errors)} warning${findings.length - errors === 1 ? '' : 's'})`;
  const before = document.createElement('div'); // "N earlier" over the list when it starts further down
  before.className = 'cp-findings-more';
  const list = document.createElement('div');
  list.className = 'cp-findings-list';
  list.setAttribute('role', 'list');
  const more = document.createElement('div');
  more.className = 'cp-findings-more';
  el.append(head, before, list, more);

  let lo = 0; // the findings shown: lo to hi (not included), at most a few pages
  let hi = 0;
  let selected = null;

  function itemHtml(f, i) {
    const sev = severityOf(meta, f);
    const robot = f.robot != null ? String(f.robot) : '';
    const rc = colours.get(robot);
    const bits = [`<span class="cp-f-kind">${escapeHtml(f.kind || 'finding')}</span>`];
    if (robot) bits.push(`<span class="cp-f-robot"${rc ? ` style="color:${css(rc)}"` : ''}>${escapeHtml(robot)}</span>`);
    if (f.time_s != null) bits.push(`<span class="cp-f-time">${clock(f.time_s)}</span>`);
    if (f.chunk) bits.push(`<span class="cp-f-chunk">chunk ${escapeHtml(f.chunk)}</span>`);
    if (f.count != null && f.count !== 1) bits.push(`<span class="cp-f-count">×${num(f.count)}${f.count_of ? ` ${escapeHtml(f.count_of)}` : ''}</span>`);
    const detail = f.detail ? `<div class="cp-f-detail">${escapeHtml(f.detail)}</div>` : '';
    return `<div class="cp-finding" role="listitem" tabindex="0" data-index="${i}" style="--cp-sev:${SEVERITY[sev]}" `
      + `title="${escapeHtml(sev)}"><div class="cp-f-top">${bits.join('')}</div>${detail}</div>`;
  }

  const items = (a, b) => {
    let html = '';
    for (let i = a; i < b; i++) html += itemHtml(findings[i], i);
    return html;
  };

  // shows findings a to b (not included): appended when they follow the list, else instead of it
  function show(a, b) {
    a = Math.max(0, a);
    b = Math.min(findings.length, b);
    if (a === hi && a >= lo) {
      list.insertAdjacentHTML('beforeend', items(a, b));
    } else {
      selected = null;
      list.innerHTML = items(a, b);
      lo = a;
    }
    hi = b;
    before.innerHTML = lo > 0 ? `<span>${num(lo)} earlier not shown</span><button type="button">show ${num(Math.min(PAGE, lo))} earlier</button>` : '';
    const left = findings.length - hi;
    more.innerHTML = left > 0 ? `<span>${num(left)} more not shown</span><button type="button">show ${num(Math.min(PAGE, left))} more</button>` : '';
  }

  function highlight(index, scroll) {
    if (selected) selected.classList.remove('cp-selected');
    selected = null;
    if (!Number.isInteger(index) || index < 0 || index >= findings.length) return;
    if (index >= hi && index < hi + PAGE) show(hi, hi + PAGE); // just after the list: one page more
    else if (index < lo || index >= hi) { // elsewhere: the page that holds it
      const a = Math.floor(index / PAGE) * PAGE;
      show(a, a + PAGE);
    }
    selected = list.children[index - lo];
    if (selected) {
      selected.classList.add('cp-selected');
      if (scroll) selected.scrollIntoView({ block: 'nearest' });
    }
  }

  function choose(item) {
    const i = Number(item.dataset.index);
    highlight(i, false);
    if (onSelect) onSelect(findings[i], i);
  }

  list.addEventListener('click', (e) => {
    const item = e.target.closest('[data-index]');
    if (item && list.contains(item)) choose(item);
  });
  list.addEventListener('keydown', (e) => {
    const item = e.target.closest('[data-index]');
    if (!item) return;
    if (e.key === 'Enter' || e.key === ' ') {
      e.preventDefault();
      choose(item);
    } else if (e.key === 'ArrowDown' || e.key === 'ArrowUp') {
      e.preventDefault();
      const next = e.key === 'ArrowDown' ? item.nextElementSibling : item.previousElementSibling;
      if (next) next.focus();
    }
  });
  more.addEventListener('click', (e) => {
    if (e.target.closest('button')) show(hi, hi + PAGE);
  });
  before.addEventListener('click', (e) => {
    if (!e.target.closest('button')) return;
    const keep = selected ? Number(selected.dataset.index) : null;
    show(lo - PAGE, hi);
    if (keep !== null) highlight(keep, false);
  });
  show(0, PAGE);

  return {
    select(index) {
      highlight(index == null ? null : Number(index), true);
    },
  };
}
