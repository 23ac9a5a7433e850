// Gonio live view: the page of a running (or finished) measurement.
//
// The server pushes Server-Sent Events (docs/live.md): one `snapshot` that replaces
// everything, then `update`s that append rows and replace what changed. This script
// keeps that state, and redraws only the parts an event touched. Plain DOM and SVG,
// no library: the page is served by the `gonio` binary and must work offline under a
// strict Content-Security-Policy (so no inline styles: SVG presentation attributes only).
'use strict';

(function () {
  const MAX_TRACE = 200;
  const MAX_DRIFT = 10000;
  const MAX_LOG = 500;
  // States after which nothing more will be measured. `created` is not one of them: it is
  // the moment before the first step.
  const ENDED = new Set(['complete', 'interrupted', 'faulted', 'stale']);
  const WARN_KINDS = new Set(['fault', 'interrupt']);
  const SOFT_KINDS = new Set(['retry', 'flagged', 'pause', 'continue', 'note']);
  // Okabe & Ito's colour-blind-safe palette, so kinds and channels stay distinguishable.
  const KIND_COLOUR = {
    sample: '#0072b2', reference: '#d55e00', dark: '#4d4d4d', incident: '#009e73', standard: '#cc79a7',
  };
  const PALETTE = ['#0072b2', '#d55e00', '#009e73', '#cc79a7', '#e69f00', '#56b4e9', '#4d4d4d'];
  // Viridis, sampled at 9 evenly spaced points (matplotlib's `viridis` colour map, CC0).
  // Perceptually uniform, so equal steps in log10 f look like equal steps in colour.
  const VIRIDIS = ['#440154', '#472c7a', '#3b518b', '#2c718e', '#21908d',
    '#27ad81', '#5cc863', '#aadc32', '#fde725'];

  const state = { run: null, status: null, now: null, trace: [], drift: [], brdf: null, report: null };
  let brdfVersion = 0; // bumped whenever a new `brdf` arrives: part of the redraw key
  let brdfDrawn = ''; // key of what #brdf shows now, so unchanged data is not redrawn
  let userIncidence = null; // [theta_i, phi_i] once the user picked one; else follow `now`
  let userChannel = null;

  const $ = (id) => document.getElementById(id);
  // The SVG namespace, taken from the page's own <svg> rather than spelled out, so that
  // no URL appears in the assets at all (they are checked for external references).
  const SVGNS = $('brdf').namespaceURI;
  const token = new URLSearchParams(window.location.search).get('token') || '';

  // ---- small helpers -------------------------------------------------------------

  const arr = (x) => (Array.isArray(x) ? x : []);
  const num = (x) => (typeof x === 'number' && Number.isFinite(x) ? x : null);
  const str = (x) => (typeof x === 'string' ? x : x == null ? '' : String(x));
  const fmtE = (x, d) => (num(x) === null ? '—' : x.toExponential(d));
  const pad2 = (n) => String(n).padStart(2, '0');

  function fmtHms(s) {
    if (num(s) === null || s < 0) return '—';
    const t = Math.round(s);
    return `${Math.floor(t / 3600)}:${pad2(Math.floor(t / 60) % 60)}:${pad2(t % 60)}`;
  }

  function fmtClock(wallS) {
    if (num(wallS) === null) return '';
    const d = new Date(wallS * 1000);
    return `${pad2(d.getHours())}:${pad2(d.getMinutes())}:${pad2(d.getSeconds())}`;
  }

  function el(tag, attrs, parent, text) {
    const e = tag.startsWith('svg:')
      ? document.createElementNS(SVGNS, tag.slice(4)) : document.createElement(tag);
    for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    if (parent) parent.appendChild(e);
    return e;
  }
  const svg = (tag, attrs, parent, text) => el('svg:' + tag, attrs, parent, text);

  const clear = (e) => { while (e.firstChild) e.removeChild(e.firstChild); };

  function viridis(t) {
    const x = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
    const i = Math.min(VIRIDIS.length - 2, Math.floor(x));
    const a = parseInt(VIRIDIS[i].slice(1), 16);
    const b = parseInt(VIRIDIS[i + 1].slice(1), 16);
    const f = x - i;
    const ch = (sh) => Math.round(((a >> sh) & 255) * (1 - f) + ((b >> sh) & 255) * f);
    return `rgb(${ch(16)},${ch(8)},${ch(0)})`;
  }

  function isEnded() {
    return ENDED.has(str(state.status && state.status.state)) || !!state.report;
  }

  // ---- header, status, controls ------------------------------------------------------

  function renderRun() {
    const run = state.run || {};
    $('run-name').textContent = str(run.name) || str(run.file) || 'live view';
    $('run-file').textContent = str(run.file);
    const det = [str(run.detector), run.unit ? `(${str(run.unit)})` : ''].join(' ').trim();
    // `live` false: this is `gonio view`, watching a run file another process may write.
    const who = run.live === false ? ' · watching the run file' : '';
    $('run-detector').textContent = (det ? `· ${det}` : '') + who;
    $('estimate').textContent = num(run.estimate_s) !== null
      ? `of ~${fmtHms(run.estimate_s)} planned` : '';
  }

  function renderStatus() {
    const s = state.status || {};
    const word = str(s.state) || '—';
    const ended = isEnded();
    const st = $('status');
    st.textContent = word;
    st.className = `state state-${word}`;
    $('status-msg').textContent = str(s.message);
    // #done counts what is finished either way, measured or given up (docs/live.md).
    const failed = Math.max(0, Math.round(num(s.failed) || 0));
    const done = Math.max(0, Math.round(num(s.done) || 0)) + failed;
    const total = Math.max(0, Math.round(num(s.total) || 0));
    $('done').textContent = String(done);
    $('total').textContent = String(total);
    $('failed').textContent = String(failed);
    $('failed-wrap').hidden = failed === 0;
    const bar = $('progress');
    bar.max = Math.max(total, 1);
    bar.value = Math.min(done, bar.max);
    $('eta').textContent = fmtHms(s.eta_s);
    $('elapsed').textContent = fmtHms(s.physical_s);
    const name = str(state.run && (state.run.name || state.run.file));
    document.title = `${word} · ${name || 'Gonio'} — Gonio live view`;

    $('final').hidden = !ended;
    // Once ended, the banner says the message; the strip below keeps only the controls.
    $('status-msg').hidden = ended;
    $('message-card').hidden = ended && !(state.run && state.run.control);
    $('final').className = `card final final-${word}`;
    $('final-state').textContent = word;
    $('final-msg').textContent = str(s.message);
    const link = $('report-link');
    // Only a same-origin path is accepted, so a bad value cannot make a javascript: link.
    const rep = str(state.report);
    link.setAttribute('href', /^\/[^/]/.test(rep) ? rep : '/report.html');
    link.hidden = !ended;
    document.body.classList.toggle('ended', ended);
    renderControls();
  }

  function renderControls() {
    const run = state.run || {};
    const ended = isEnded();
    $('controls').hidden = !run.control;
    const paused = str(state.status && state.status.state) === 'paused';
    const pause = $('pause');
    const stop = $('stop');
    pause.textContent = paused ? 'Resume' : 'Pause';
    for (const b of [pause, stop]) {
      b.hidden = ended;
      b.disabled = ended || pending;
    }
    if (ended) disarmStop();
  }

  // Stop needs two clicks within 5 s (a confirm() dialog would block browser tests).
  let stopArmed = null;
  let pending = false;

  function disarmStop() {
    if (stopArmed) clearTimeout(stopArmed);
    stopArmed = null;
    $('stop').textContent = 'Stop';
    $('stop').classList.remove('armed');
  }

  async function control(action) {
    const said = { stop: 'stop requested', pause: 'paused', resume: 'resumed' };
    const msg = $('control-msg');
    pending = true;
    renderControls();
    msg.textContent = `${action}…`;
    msg.className = 'control-msg';
    try {
      // The token travels only in this header: never in a link or a form.
      const resp = await fetch(`/control/${action}`, {
        method: 'POST', headers: { 'X-Gonio-Token': token }, cache: 'no-store',
      });
      let body = null;
      try { body = await resp.json(); } catch (_) { body = null; }
      if (resp.ok) {
        msg.textContent = said[action];
        msg.classList.add('ok');
      } else {
        msg.textContent = str(body && body.error) || `refused (HTTP ${resp.status})`;
        msg.classList.add('bad');
      }
    } catch (_) {
      msg.textContent = 'no answer from the server';
      msg.classList.add('bad');
    }
    pending = false;
    renderControls();
  }

  function wireControls() {
    $('pause').addEventListener('click', () => {
      const paused = str(state.status && state.status.state) === 'paused';
      control(paused ? 'resume' : 'pause');
    });
    $('stop').addEventListener('click', () => {
      if (stopArmed) {
        disarmStop();
        control('stop');
        return;
      }
      $('stop').textContent = 'Confirm stop';
      $('stop').classList.add('armed');
      stopArmed = setTimeout(disarmStop, 5000);
    });
    $('incidence').addEventListener('change', (e) => {
      const inc = arr(state.brdf && state.brdf.incidences)[Number(e.target.value)];
      userIncidence = Array.isArray(inc) ? inc : null;
      renderBrdf();
    });
    $('channel').addEventListener('change', (e) => {
      userChannel = Number(e.target.value);
      renderBrdf();
    });
  }

  // ---- the latest reading ------------------------------------------------------------

  function renderNow() {
    const run = state.run || {};
    const now = state.now;
    const axes = arr(run.axes);
    const pos = arr(now && now.position);
    const dl = $('positions');
    clear(dl);
    for (let i = 0; i < Math.max(4, axes.length); i++) {
      const row = el('div', { class: 'axis' }, dl);
      el('dt', {}, row, str(axes[i]) || `axis ${i + 1}`);
      // `+ 0` turns a -0.0004 into 0, so that an axis at rest does not read "-0.000°".
      const v = num(pos[i]);
      el('dd', { class: 'num' }, row, v === null ? '—' : `${(+v.toFixed(3) + 0).toFixed(3)}°`);
    }
    const r = $('reading');
    clear(r);
    if (!now) {
      el('span', { class: 'muted' }, r, 'no reading yet');
      return;
    }
    const kind = str(now.kind);
    const head = el('div', { class: 'reading-head' }, r);
    el('span', { class: `kind kind-${kind}` }, head, kind || '?');
    if (now.channel != null) el('span', { class: 'chan' }, head, str(now.channel));
    if (now.step_id != null) el('span', { class: 'muted' }, head, `step ${str(now.step_id)}`);
    el('div', { class: 'value num' }, r,
      `${fmtE(now.r_mean, 3)} ± ${fmtE(now.r_std, 1)} ${str(run.unit)}`);
    const pair = arr(now.pair).map(num);
    if (pair.length === 4 && pair.every((x) => x !== null)) {
      el('div', { class: 'muted small' }, r, `θi ${pair[0].toFixed(1)}°, φi ${pair[1].toFixed(1)}°`
        + ` → θo ${pair[2].toFixed(1)}°, φo ${pair[3].toFixed(1)}°`);
    }
    if (str(now.flag_text)) el('div', { class: 'flag' }, r, `flags: ${str(now.flag_text)}`);
  }

  // ---- BRDF on the projected hemisphere --------------------------------------------

  const near = (a, b) => Math.abs(a[0] - b[0]) < 1e-6 && Math.abs(a[1] - b[1]) < 1e-6;

  // Fill a <select> only when its option list changed, so an open list or the keyboard
  // focus is not lost at every update.
  function setOptions(sel, labels, chosen) {
    const key = labels.join('\n');
    if (sel.dataset.key !== key) {
      clear(sel);
      labels.forEach((l, i) => el('option', { value: String(i) }, sel, l));
      sel.dataset.key = key;
    }
    if (chosen >= 0) sel.value = String(chosen);
  }

  // The incidence shown: the user's choice while it exists, else the one nearest the
  // latest reading's (read back, so not exactly the planned angles), else the first.
  function chooseIncidence(incs) {
    if (userIncidence) {
      const i = incs.findIndex((x) => near(x, userIncidence));
      if (i >= 0) return i;
    }
    const p = arr(state.now && state.now.pair);
    let best = incs.length ? 0 : -1;
    let bestD = 1.0; // degrees: farther than this, the reading is not at a sampled incidence
    if (num(p[0]) !== null && num(p[1]) !== null) {
      incs.forEach((x, i) => {
        const dphi = Math.abs(((x[1] - p[1]) % 360 + 540) % 360 - 180);
        const d = Math.abs(x[0] - p[0]) + (x[0] > 0.5 ? dphi : 0);
        if (d < bestD) { bestD = d; best = i; }
      });
    }
    return best;
  }

  function renderBrdf() {
    const b = state.brdf || {};
    const channels = arr(b.channels).map(str);
    const n = Math.max(1, channels.length);
    const incs = arr(b.incidences).filter((x) => Array.isArray(x) && x.length >= 2);
    const ii = chooseIncidence(incs);
    const ci = userChannel !== null && userChannel < n ? userChannel : 0;
    const incLabel = (x) => `θi ${(+x[0]).toFixed(1)}°, φi ${(+x[1]).toFixed(1)}°`;
    setOptions($('incidence'), incs.map(incLabel), ii);
    $('incidence').disabled = incs.length === 0;
    setOptions($('channel'), channels, ci);
    $('channel-wrap').hidden = channels.length <= 1;
    const note = $('brdf-note');
    note.textContent = str(b.note);
    note.hidden = !b.note;

    const key = `${brdfVersion}|${ii >= 0 ? incs[ii].join(',') : ''}|${ci}`;
    if (key === brdfDrawn) return;
    brdfDrawn = key;

    const inc = ii >= 0 ? incs[ii] : null;
    const rows = inc ? arr(b.samples).filter((r) => Array.isArray(r) && r.length >= 4 + 2 * n
      && near([r[0], r[1]], inc) && num(r[2]) !== null && num(r[3]) !== null) : [];
    const root = $('brdf');
    clear(root);
    const cx = 185, cy = 172, R = 135;
    const toXY = (th, ph) => {
      const s = Math.sin(th * Math.PI / 180);
      const a = ph * Math.PI / 180;
      // SVG's y grows downwards; φ = 90° is drawn up.
      return [cx + R * s * Math.cos(a), cy - R * s * Math.sin(a)];
    };
    const grid = svg('g', { class: 'grid' }, root);
    svg('circle', { cx, cy, r: R, class: 'disk' }, grid);
    for (let ph = 0; ph < 360; ph += 30) {
      const [x, y] = toXY(90, ph);
      svg('line', { x1: cx, y1: cy, x2: x, y2: y }, grid);
    }
    for (const th of [30, 60]) svg('circle', { cx, cy, r: R * Math.sin(th * Math.PI / 180) }, grid);
    for (const th of [30, 60, 90]) {
      const [x, y] = toXY(th, 45);
      svg('text', { x: x + 3, y: y - 3, class: 'tick' }, grid, `${th}°`);
    }
    for (const ph of [0, 90, 180, 270]) {
      const [x, y] = toXY(90, ph);
      const c = Math.cos(ph * Math.PI / 180), s = Math.sin(ph * Math.PI / 180);
      const anchor = c > 0.5 ? 'start' : c < -0.5 ? 'end' : 'middle';
      const at = { x: x + c * 5, y: y - s * 8 + 4, class: 'tick', 'text-anchor': anchor };
      svg('text', at, grid, `φ ${ph}°`);
    }

    const fs = rows.map((r) => r[4 + ci]).filter((f) => num(f) !== null && f > 0).map(Math.log10);
    const lo = fs.length ? Math.min(...fs) : 0;
    const hi = fs.length ? Math.max(...fs) : 0;
    const rad = Math.max(2, Math.min(5, (R * 0.6) / Math.sqrt(rows.length + 1)));
    const pts = svg('g', { class: 'pts' }, root);
    for (const r of rows) {
      const [to, po, f, s, flags] = [r[2], r[3], r[4 + ci], r[4 + n + ci], r[4 + 2 * n]];
      const [x, y] = toXY(to, po);
      const ok = num(f) !== null && f > 0;
      const t = hi > lo ? (Math.log10(f) - lo) / (hi - lo) : 0.5;
      const c = svg('circle', {
        cx: x.toFixed(2), cy: y.toFixed(2), r: rad.toFixed(2),
        class: `pt${ok ? '' : ' nonpos'}${num(flags) ? ' flagged' : ''}`,
        fill: ok ? viridis(t) : '#bbbbbb',
      }, pts);
      const tail = num(flags) ? ` (flags ${flags})` : '';
      svg('title', {}, c,
        `θo ${to.toFixed(1)}°, φo ${po.toFixed(1)}°: f = ${fmtE(f, 3)} ± ${fmtE(s, 1)} /sr${tail}`);
    }
    $('brdf-count').textContent = String(pts.childNodes.length);
    if (inc) {
      // The mirror direction, where a glossy lobe should peak; drawn over the points but
      // transparent to the mouse (CSS), so their titles still show.
      const [sx, sy] = toXY(+inc[0], +inc[1] + 180);
      svg('path', { d: `M${sx - 7},${sy}h14M${sx},${sy - 7}v14`, class: 'specular' }, root);
      svg('path', { d: 'M14,326h10M19,321v10', class: 'specular' }, root);
      svg('text', { x: 30, y: 330, class: 'tick' }, root, 'mirror direction');
    }
    if (!rows.length) {
      svg('text', { x: cx, y: cy + 4, class: 'empty', 'text-anchor': 'middle' }, root, 'no points yet');
    }

    // Colour bar for log10 f, with the f range at its ends.
    const bx = 370, by = 42, bh = 260;
    const grad = svg('linearGradient', { id: 'viridis', x1: 0, y1: 1, x2: 0, y2: 0 }, svg('defs', {}, root));
    VIRIDIS.forEach((c, i) => svg('stop', { offset: i / (VIRIDIS.length - 1), 'stop-color': c }, grad));
    svg('rect', { x: bx, y: by, width: 14, height: bh, fill: 'url(#viridis)', class: 'bar' }, root);
    const barTitle = channels.length > 1 ? `f /sr · ${channels[ci]}` : 'f /sr';
    svg('text', { x: bx - 4, y: by - 14, class: 'tick' }, root, barTitle);
    if (fs.length) {
      for (const [v, y] of [[hi, by], [(lo + hi) / 2, by + bh / 2], [lo, by + bh]]) {
        svg('text', { x: bx + 19, y: y + 4, class: 'tick' }, root, (10 ** v).toExponential(2));
      }
    }
  }

  // ---- line charts: trace and drift ---------------------------------------------------

  // Round tick values, about n of them, covering [lo, hi].
  function ticks(lo, hi, n) {
    if (!(hi > lo)) return [lo];
    const raw = (hi - lo) / n;
    const mag = 10 ** Math.floor(Math.log10(raw));
    const r = raw / mag;
    const step = (r < 1.5 ? 1 : r < 3 ? 2 : r < 7 ? 5 : 10) * mag;
    const out = [];
    for (let v = Math.ceil(lo / step - 1e-9) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    return out;
  }

  // Ticks of a log axis (log10 values): decades, or 1-2-5 in each decade, or every
  // digit, whichever first gives at least three inside [lo, hi] (at most eight).
  function logTicks(lo, hi) {
    let best = [];
    for (const ms of [[1], [1, 2, 5], [1, 2, 3, 4, 5, 6, 7, 8, 9]]) {
      const out = [];
      for (let k = Math.floor(lo); k <= Math.ceil(hi); k++) {
        for (const m of ms) {
          const v = k + Math.log10(m);
          if (v >= lo && v <= hi) out.push(v);
        }
      }
      if (out.length > 8) break;
      best = out;
      if (out.length >= 3) break;
    }
    return best.length ? best : ticks(lo, hi, 4);
  }

  // Short labels: 0.25, 1200, 1.5e-7 (trailing zeros of the mantissa dropped).
  const fmtTick = (v) => (v === 0 ? '0' : Math.abs(v) >= 1e4 || Math.abs(v) < 1e-2
    ? v.toExponential(2).replace(/\.?0+e/, 'e') : String(+v.toPrecision(3)));

  // Axes and grid of a chart; returns the scales. `ylog` takes and labels log10 values.
  function frame(root, xr, yr, opts) {
    const W = 560, H = 250;
    const box = { l: 62, r: W - 12, t: 26, b: H - 34 };
    const pad = (lo, hi) => (hi > lo ? [lo - (hi - lo) * 0.05, hi + (hi - lo) * 0.05]
      : [lo - (Math.abs(lo) || 1) * 0.1, hi + (Math.abs(hi) || 1) * 0.1]);
    const [x0, x1] = xr[1] > xr[0] ? xr : [xr[0] - 1, xr[0] + 1];
    const [y0, y1] = pad(yr[0], yr[1]);
    const X = (v) => box.l + (v - x0) / (x1 - x0) * (box.r - box.l);
    const Y = (v) => box.b - (v - y0) / (y1 - y0) * (box.b - box.t);
    const g = svg('g', { class: 'grid' }, root);
    const yt = opts.ylog ? logTicks(y0, y1) : ticks(y0, y1, 5);
    for (const v of yt) {
      svg('line', { x1: box.l, x2: box.r, y1: Y(v), y2: Y(v) }, g);
      const label = opts.ylog ? fmtTick(+(10 ** v).toPrecision(2)) : fmtTick(v);
      svg('text', { x: box.l - 5, y: Y(v) + 4, 'text-anchor': 'end', class: 'tick' }, g, label);
    }
    for (const v of ticks(x0, x1, 6)) {
      svg('line', { x1: X(v), x2: X(v), y1: box.t, y2: box.b }, g);
      svg('text', { x: X(v), y: box.b + 15, 'text-anchor': 'middle', class: 'tick' }, g,
        opts.xlabel ? opts.xlabel(v) : fmtTick(v));
    }
    svg('rect', { x: box.l, y: box.t, width: box.r - box.l, height: box.b - box.t, class: 'frame' }, root);
    const mid = (box.l + box.r) / 2;
    svg('text', { x: mid, y: H - 4, 'text-anchor': 'middle', class: 'axis-title' }, root, opts.xtitle);
    svg('text', { x: 4, y: 14, class: 'axis-title' }, root, opts.ytitle);
    return { X, Y, box };
  }

  // A row of legend items ending at `right`; text is measured once drawn (the font is
  // loaded from /font.ttf, so its widths are not known in advance).
  function legend(root, items, right) {
    const groups = items.map(([label, colour]) => {
      const g = svg('g', { class: 'legend' }, root);
      svg('circle', { cx: 4, cy: 10, r: 4, fill: colour }, g);
      const t = svg('text', { x: 11, y: 14, class: 'tick' }, g, label);
      const w = t.getComputedTextLength ? t.getComputedTextLength() : 0;
      return [g, 11 + (w > 0 ? w : label.length * 6.5) + 12];
    });
    let x = right - groups.reduce((a, [, w]) => a + w, 0) + 12;
    for (const [g, w] of groups) {
      g.setAttribute('transform', `translate(${x.toFixed(1)},0)`);
      x += w;
    }
  }

  function emptyChart(root, text) {
    svg('text', { x: 280, y: 128, 'text-anchor': 'middle', class: 'empty' }, root, text);
  }

  function renderTrace() {
    const root = $('trace');
    clear(root);
    const rows = state.trace.filter((r) => r && num(r.r_mean) !== null);
    const unit = str(state.run && state.run.unit);
    if (!rows.length) return emptyChart(root, 'no readings yet');
    // A log axis shows references and dark readings decades apart on one plot.
    const ylog = rows.every((r) => r.r_mean > 0);
    const tf = ylog ? Math.log10 : (v) => v;
    const ys = rows.map((r) => tf(r.r_mean));
    const { X, Y, box } = frame(root, [0, rows.length - 1], [Math.min(...ys), Math.max(...ys)], {
      ylog, xtitle: 'reading (step order; labels are step ids)', ytitle: `r_mean / ${unit || '?'}`,
      xlabel: (v) => (rows[Math.round(v)] ? str(rows[Math.round(v)].step_id) : ''),
    });
    const clampY = (v) => Math.min(box.b, Math.max(box.t, v));
    const thread = rows.map((r, i) => `${X(i).toFixed(1)},${Y(ys[i]).toFixed(1)}`).join(' ');
    svg('polyline', { points: thread, class: 'thread' }, root);
    const kinds = [];
    rows.forEach((r, i) => {
      const kind = str(r.kind);
      if (!kinds.includes(kind)) kinds.push(kind);
      const colour = KIND_COLOUR[kind] || '#777777';
      const x = X(i);
      const s = num(r.r_std);
      if (s !== null && s > 0) {
        const lo = r.r_mean - s > 0 || !ylog ? Y(tf(r.r_mean - s)) : box.b;
        const hi = Y(tf(r.r_mean + s));
        if (Math.abs(lo - hi) > 1.5) {
          svg('line', { x1: x, x2: x, y1: clampY(lo), y2: clampY(hi), stroke: colour, class: 'err' }, root);
        }
      }
      const c = svg('circle', {
        cx: x.toFixed(1), cy: Y(ys[i]).toFixed(1), r: 2.6, fill: colour, class: num(r.flags) ? 'flagged' : '',
      }, root);
      svg('title', {}, c, `step ${str(r.step_id)} ${kind}${r.channel != null ? ' ' + str(r.channel) : ''}: `
        + `${fmtE(r.r_mean, 3)} ± ${fmtE(r.r_std, 1)} ${unit}`);
    });
    legend(root, kinds.map((k) => [k || '?', KIND_COLOUR[k] || '#777777']), box.r);
  }

  function renderDrift() {
    const root = $('drift');
    clear(root);
    const rows = state.drift.filter((r) => r && num(r.r_mean) !== null && num(r.physical_s) !== null);
    // Each channel is compared with its own first reading: channels differ in level.
    const series = new Map();
    for (const r of rows) {
      const ch = str(r.channel);
      if (!series.has(ch)) {
        if (r.r_mean === 0) continue;
        series.set(ch, { ref: r.r_mean, pts: [] });
      }
      const s = series.get(ch);
      s.pts.push([r.physical_s, (r.r_mean / s.ref - 1) * 100]);
    }
    if (!series.size) return emptyChart(root, 'no drift-reference readings yet');
    const all = [...series.values()].flatMap((s) => s.pts);
    const xs = all.map((p) => p[0]);
    const ys = all.map((p) => p[1]);
    const span = Math.max(...xs) - Math.min(...xs);
    const [div, u] = span >= 7200 ? [3600, 'h'] : [60, 'min'];
    const { X, Y, box } = frame(root, [Math.min(...xs) / div, Math.max(...xs) / div],
      [Math.min(0, ...ys), Math.max(0, ...ys)], {
        xtitle: `instrument time / ${u}`, ytitle: 'reference / first − 1  (%)',
      });
    svg('line', { x1: box.l, x2: box.r, y1: Y(0), y2: Y(0), class: 'zero' }, root);
    const items = [];
    let k = 0;
    for (const [ch, s] of series) {
      const colour = PALETTE[k++ % PALETTE.length];
      items.push([ch || 'drift', colour]);
      svg('polyline', {
        points: s.pts.map((p) => `${X(p[0] / div).toFixed(1)},${Y(p[1]).toFixed(1)}`).join(' '),
        stroke: colour, class: 'series',
      }, root);
      // Markers only while they stay apart; a long run is read from the line alone.
      if (s.pts.length <= 300) {
        for (const p of s.pts) {
          svg('circle', { cx: X(p[0] / div).toFixed(1), cy: Y(p[1]).toFixed(1), r: 2.2, fill: colour }, root);
        }
      }
    }
    legend(root, items, box.r);
  }

  // ---- event log ---------------------------------------------------------------------

  function logRow(r) {
    const kind = str(r && r.kind);
    const cls = WARN_KINDS.has(kind) ? 'warn' : SOFT_KINDS.has(kind) ? 'soft' : '';
    const tr = el('tr', cls ? { class: cls } : {});
    el('td', { class: 'num' }, tr, fmtClock(r && r.wall_s));
    el('td', {}, tr, kind);
    el('td', { class: 'num' }, tr, r && r.step_id != null ? str(r.step_id) : '');
    el('td', {}, tr, str(r && r.message));
    return tr;
  }

  // Append rows and keep the newest in view, unless the user scrolled up to read.
  function appendLog(rows, replace) {
    const box = $('log-scroll');
    const body = $('log').tBodies[0];
    const atBottom = box.scrollHeight - box.scrollTop - box.clientHeight < 24;
    if (replace) clear(body);
    const frag = document.createDocumentFragment();
    for (const r of rows) frag.appendChild(logRow(r));
    body.appendChild(frag);
    while (body.rows.length > MAX_LOG) body.deleteRow(0);
    if (atBottom) box.scrollTop = box.scrollHeight;
  }

  // ---- the event stream ----------------------------------------------------------------

  function apply(d, snapshot) {
    if (!d || typeof d !== 'object') return;
    if (snapshot) {
      state.run = d.run || null;
      state.status = d.status || null;
      state.now = d.now || null;
      state.trace = arr(d.trace).slice(-MAX_TRACE);
      state.drift = arr(d.drift).slice(-MAX_DRIFT);
      state.brdf = d.brdf || null;
      state.report = d.report || null;
      brdfVersion++;
      renderRun();
      appendLog(arr(d.log).slice(-MAX_LOG), true);
    } else {
      // Absent keys did not change; present ones replace (or, for rows, append).
      for (const k of ['status', 'now', 'report']) if (k in d) state[k] = d[k];
      if ('brdf' in d) { state.brdf = d.brdf; brdfVersion++; }
      if (arr(d.trace).length) state.trace = state.trace.concat(d.trace).slice(-MAX_TRACE);
      if (arr(d.drift).length) state.drift = state.drift.concat(d.drift).slice(-MAX_DRIFT);
      if (arr(d.log).length) appendLog(d.log, false);
    }
    renderStatus();
    if (snapshot || 'now' in d) renderNow();
    renderBrdf(); // cheap when nothing changed: it compares a key first
    if (snapshot || arr(d.trace).length) renderTrace();
    if (snapshot || arr(d.drift).length) renderDrift();
  }

  function setConnection(word, alarm) {
    const c = $('connection');
    c.textContent = word;
    c.className = `conn conn-${word}${alarm ? ' alarm' : ''}`;
  }

  function connect() {
    const es = new EventSource('/events');
    const handle = (snapshot) => (e) => {
      let d = null;
      try { d = JSON.parse(e.data); } catch (_) { return; } // a torn event: wait for the next
      setConnection('live', false);
      apply(d, snapshot);
    };
    es.addEventListener('snapshot', handle(true));
    es.addEventListener('update', handle(false));
    es.addEventListener('open', () => setConnection('live', false));
    es.addEventListener('error', () => {
      const ended = isEnded();
      if (es.readyState === EventSource.CLOSED) {
        // The browser gave up (e.g. 503 when too many streams are open): try again later.
        setConnection('closed', !ended);
        setTimeout(connect, 10000);
      } else {
        // The browser retries by itself. After the end, the server going away is normal.
        setConnection(ended ? 'closed' : 'reconnecting', !ended);
      }
    });
  }

  function start() {
    wireControls();
    renderRun();
    renderStatus();
    renderNow();
    renderBrdf();
    renderTrace();
    renderDrift();
    connect();
    // Legends are laid out by measured text width: measure again with the real font.
    if (document.fonts) document.fonts.ready.then(() => { renderTrace(); renderDrift(); });
  }

  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
