// The live view of a run: polls the run's status and new frames, shows the latest renders.
'use strict';

const live = {
  kind: ['shaded', 'color', 'normals', 'levels'].includes(hv.params.get('mode')) ? hv.params.get('mode') : 'shaded',
  frames: [],
  status: null,
  renderVersion: -1,
  failures: 0,
};

const stageColors = { track: '#4fa3f7', allocate: '#a371f7', integrate: '#3fb950', refine: '#d29922', raycast: '#f85149' };
const verdictColors = { good: '#3fb950', poor: '#d29922', lost: '#f85149' };

function setMode(kind) {
  live.kind = kind;
  for (const b of document.querySelectorAll('#modes button')) b.classList.toggle('on', b.dataset.kind === kind);
  document.getElementById('level-legend').style.visibility = kind === 'levels' ? 'visible' : 'hidden';
  showRender();
}

function showRender() {
  const s = live.status;
  if (!s || !s.render_version) return;
  document.getElementById('render').src = `/api/render/${live.kind}.png?v=${s.render_version}`;
  document.getElementById('depth').src = `/api/render/depth.png?v=${s.render_version}`;
  document.getElementById('render-info').textContent = `frame ${s.render_frame}`;
  const [lo, hi] = s.depth_range_m;
  document.getElementById('depth-min').textContent = `${lo.toFixed(2)} m`;
  document.getElementById('depth-max').textContent = `${hi.toFixed(2)} m`;
  live.renderVersion = s.render_version;
  document.body.dataset.renderVersion = s.render_version;
  // Where the model's picture is on the page (for tests that look at screenshots).
  const r = document.getElementById('render').getBoundingClientRect();
  document.body.dataset.renderRect = [r.left, r.top, r.width, r.height].map(Math.round).join(',');
}

function drawDepthScale() {
  const c = document.getElementById('depth-scale'), g = c.getContext('2d');
  for (let x = 0; x < c.width; ++x) {
    const [r, gr, b] = hv.depthRamp(x / (c.width - 1));
    g.fillStyle = `rgb(${r},${gr},${b})`;
    g.fillRect(x, 0, 1, 1);
  }
}

// Camera positions projected on the plane of their two widest axes (seen from the third).
function drawTrajectory() {
  const c = document.getElementById('trajectory');
  const dpr = window.devicePixelRatio || 1, w = c.clientWidth || 400, h = c.clientHeight || 300;
  c.width = w * dpr; c.height = h * dpr;
  const g = c.getContext('2d');
  g.scale(dpr, dpr);
  g.clearRect(0, 0, w, h);
  const ps = live.frames.map(f => f.p);
  if (ps.length === 0) return;
  const lo = [0, 1, 2].map(a => Math.min(...ps.map(p => p[a]))), hi = [0, 1, 2].map(a => Math.max(...ps.map(p => p[a])));
  const axes = [0, 1, 2].sort((a, b) => (hi[b] - lo[b]) - (hi[a] - lo[a])).slice(0, 2).sort();
  const span = Math.max(hi[axes[0]] - lo[axes[0]], hi[axes[1]] - lo[axes[1]], 0.05);
  const scale = Math.min(w - 40, h - 40) / span;
  const cx = (lo[axes[0]] + hi[axes[0]]) / 2, cy = (lo[axes[1]] + hi[axes[1]]) / 2;
  const P = p => [w / 2 + (p[axes[0]] - cx) * scale, h / 2 + (p[axes[1]] - cy) * scale];
  g.lineWidth = 1.5;
  for (let i = 1; i < ps.length; ++i) {
    g.strokeStyle = verdictColors[live.frames[i].tracking] || '#4fa3f7';
    g.beginPath(); g.moveTo(...P(ps[i - 1])); g.lineTo(...P(ps[i])); g.stroke();
  }
  const [x, y] = P(ps[ps.length - 1]);
  g.fillStyle = '#fff'; g.beginPath(); g.arc(x, y, 4, 0, 2 * Math.PI); g.fill();
  // scale bar
  const names = ['x', 'y', 'z'];
  const bar = Math.pow(10, Math.floor(Math.log10(span / 2)));
  g.strokeStyle = '#9aa1ab'; g.fillStyle = '#9aa1ab'; g.font = '11px system-ui';
  g.beginPath(); g.moveTo(10, h - 10); g.lineTo(10 + bar * scale, h - 10); g.stroke();
  g.fillText(`${bar >= 1 ? bar + ' m' : bar * 100 + ' cm'}  (plane ${names[axes[0]]}${names[axes[1]]})`, 10, h - 14);
}

function drawCharts() {
  const s = live.status, f = live.frames;
  if (!s) return;
  const xs = f.map(x => x.i);
  hv.chart(document.getElementById('blocks'),
    s.level_colors.map((color, l) => ({ name: `level ${l} (${+s.voxel_sizes_mm[l].toFixed(2)} mm)`, color,
                                        values: f.map(x => x.blocks[l] || 0) })), { xs });
  hv.chart(document.getElementById('times'),
    Object.entries(stageColors).map(([name, color]) => ({ name, color, values: f.map(x => x.ms[name]) })),
    { xs, yLabel: 'ms', stacked: true, robust: true });
  const v = document.getElementById('verdicts'), g = v.getContext('2d');
  v.width = v.clientWidth || 400; v.height = v.clientHeight || 36;
  g.clearRect(0, 0, v.width, v.height);
  f.forEach((x, i) => {
    g.fillStyle = x.fused ? verdictColors[x.tracking] : verdictColors.lost;
    g.fillRect(Math.floor(i * v.width / f.length), 0, Math.ceil(v.width / f.length), v.height);
  });
  drawTrajectory();
}

function showStatus() {
  const s = live.status;
  document.getElementById('source').textContent = s.source;
  document.getElementById('settings').textContent = s.settings;
  const done = s.frames_done, total = s.frames_total;
  document.getElementById('bar').style.width = `${total ? (100 * done / total) : 0}%`;
  const fps = s.elapsed_s > 0 ? done / s.elapsed_s : 0;
  document.getElementById('progress-text').textContent = `frame ${done} of ${total} · ${fps.toFixed(1)} fps`;
  const state = document.getElementById('state');
  state.textContent = s.state + (s.message ? ` — ${s.message}` : '');
  state.className = s.state;
  document.body.dataset.state = s.state;
  document.body.dataset.frames = done;
  hv.levelLegend(document.getElementById('level-legend'), s.level_colors, s.voxel_sizes_mm);
  document.getElementById('blocks-info').textContent =
    `${hv.count(s.blocks_total)} blocks (peak ${hv.count(s.peak_blocks)}), ${hv.bytes(s.memory_bytes)}` +
    (s.dropped_blocks ? `, ${hv.count(s.dropped_blocks)} dropped (pool full)` : '');
  const last = live.frames.slice(-30);
  const mean = last.length ? last.reduce((a, x) => a + x.ms.total, 0) / last.length : 0;
  document.getElementById('fps').textContent = last.length ? `last ${last.length} frames: ${mean.toFixed(1)} ms per frame processing` : '';
  const t = s.tracking_counts, tr = document.getElementById('tracking');
  tr.replaceChildren(...(s.tracking ? ['good', 'poor', 'lost'] : ['good']).map(k => hv.el('span', {},
    hv.el('i', { style: `background:${verdictColors[k]}` }), s.tracking ? `${k} ${hv.count(t[k])}` : 'poses given (no tracking)')));
}

async function poll() {
  try {
    live.status = await hv.json('/api/status.json');
    const more = await hv.json(`/api/frames.json?from=${live.frames.length}`);
    if (more.from === live.frames.length) live.frames.push(...more.frames);
    live.failures = 0;
    showStatus();
    drawCharts();
    if (live.status.render_version !== live.renderVersion) showRender();
  } catch (e) {
    if (++live.failures >= 2) {
      const state = document.getElementById('state');
      state.textContent = live.status && live.status.state !== 'running'
        ? `${live.status.state}; the run's server has closed (see its results with hivox view)`
        : 'no connection to the run';
      state.className = 'offline';
      document.body.dataset.state = 'offline';
    }
  }
  const running = !live.status || live.status.state === 'running' || live.status.state === 'starting';
  setTimeout(poll, running ? 500 : 2000);
}

for (const b of document.querySelectorAll('#modes button')) b.onclick = () => setMode(b.dataset.kind);
drawDepthScale();
setMode(live.kind);
poll();
