// Helpers the live view and the viewer share: fetching, number formats, legends, charts.
'use strict';

const hv = {
  params: new URLSearchParams(location.search),

  async json(url) {
    const r = await fetch(url, { cache: 'no-store' });
    if (!r.ok) throw new Error(`${url}: ${r.status} ${await r.text()}`);
    return r.json();
  },

  el(tag, attrs = {}, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) {
      if (k === 'style') e.style.cssText = v; else e.setAttribute(k, v);
    }
    for (const c of children) e.append(c);
    return e;
  },

  count(n) { return Number(n).toLocaleString('en-US'); },
  bytes(n) { return n >= 1 << 30 ? `${(n / (1 << 30)).toFixed(2)} GiB` : `${(n / (1 << 20)).toFixed(1)} MiB`; },
  length(m) { return m < 0.01 ? `${(m * 1000).toFixed(2)} mm` : `${(m * 100).toFixed(2)} cm`; },

  // The level legend: a swatch per level with its voxel size.
  levelLegend(container, colors, sizesMm, counts) {
    container.replaceChildren();
    colors.forEach((c, l) => {
      const size = sizesMm && sizesMm[l] > 0 ? ` · ${+sizesMm[l].toFixed(2)} mm` : '';
      const n = counts ? ` · ${hv.count(counts[l])}` : '';
      container.append(hv.el('span', { 'data-level': l }, hv.el('i', { style: `background:${c}` }),
                             `level ${l}${l === 0 ? ' (finest)' : ''}${size}${n}`));
    });
  },

  // The colours of hivox's depth renders (near dark blue ... far red), t in [0, 1].
  depthRamp(t) {
    const stops = [[0.10, 0.10, 0.45], [0.10, 0.65, 0.90], [0.25, 0.80, 0.30], [0.95, 0.85, 0.20],
                   [0.85, 0.15, 0.10]];
    t = Math.min(Math.max(t, 0), 1) * 4;
    const k = Math.min(3, Math.floor(t)), f = t - k;
    return stops[k].map((a, i) => Math.round(255 * (a + (stops[k + 1][i] - a) * f)));
  },

  // Line chart on a canvas: series [{name, color, values}] over x = 0..n-1 (or xs).
  // robust: the scale ignores the top 2 % of the values (a spike when the machine was busy would
  // flatten everything else); what exceeds it is drawn at the top.
  chart(canvas, series, { xs = null, yLabel = '', stacked = false, robust = false } = {}) {
    const dpr = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || 400, h = canvas.clientHeight || 220;
    canvas.width = w * dpr; canvas.height = h * dpr;
    const g = canvas.getContext('2d');
    g.scale(dpr, dpr);
    g.clearRect(0, 0, w, h);
    const n = Math.max(0, ...series.map(s => s.values.length));
    const left = 52, right = 8, top = 22, bottom = 22;
    const totals = stacked ? Array.from({ length: n }, (_, i) => series.reduce((a, s) => a + (s.values[i] || 0), 0)) : null;
    const all = stacked ? totals : series.flatMap(s => s.values);
    let ymax = Math.max(1e-9, ...all);
    if (robust && all.length > 50) {
      const sorted = [...all].sort((a, b) => a - b);
      ymax = Math.max(1e-9, Math.min(ymax, 1.3 * sorted[Math.floor(0.98 * (sorted.length - 1))]));
    }
    ymax *= 1.05;
    const X = i => left + (n <= 1 ? 0 : (i / (n - 1)) * (w - left - right));
    const Y = v => h - bottom - (Math.min(v, ymax) / ymax) * (h - top - bottom);
    g.strokeStyle = '#2e333b'; g.fillStyle = '#9aa1ab'; g.font = '11px system-ui'; g.lineWidth = 1;
    for (let k = 0; k <= 4; ++k) {
      const v = (ymax / 1.05) * k / 4, y = Y(v);
      g.beginPath(); g.moveTo(left, y); g.lineTo(w - right, y); g.stroke();
      g.fillText(v >= 1000 ? `${(v / 1000).toFixed(v >= 1e4 ? 0 : 1)}k` : v.toFixed(v < 10 ? 1 : 0), 4, y + 4);
    }
    if (n > 0) {
      const x0 = xs ? xs[0] : 0, x1 = xs ? xs[n - 1] : n - 1;
      g.fillText(`frame ${x0}`, left, h - 6);
      const label = `${x1}`;
      g.fillText(label, w - right - g.measureText(label).width, h - 6);
    }
    if (yLabel) g.fillText(yLabel, left, 12);
    let lx = left + (yLabel ? g.measureText(yLabel).width + 14 : 0);
    const base = new Array(n).fill(0);
    for (const s of series) {
      g.strokeStyle = s.color; g.fillStyle = s.color; g.lineWidth = 1.5;
      g.beginPath();
      s.values.forEach((v, i) => {
        const y = Y(stacked ? (base[i] += v) : v);
        i ? g.lineTo(X(i), y) : g.moveTo(X(i), y);
      });
      g.stroke();
      g.fillRect(lx, 5, 10, 10);
      g.fillStyle = '#e4e6ea';
      g.fillText(s.name, lx + 13, 14);
      lx += g.measureText(s.name).width + 26;
    }
  },
};
