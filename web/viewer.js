// The viewer of results: the mesh in three.js with orbit controls, coloured by fused colour,
// refinement level or normal, with the camera trajectory, the level legend and the run's stats.
'use strict';

const viewer = { info: null, mesh: null, colors: {}, trajectory: null };

// The binary mesh of /api/mesh.bin (hivox::mesh_to_binary).
function decodeMesh(buffer) {
  const magic = new TextDecoder().decode(new Uint8Array(buffer, 0, 8));
  if (magic !== 'HVXMESH1') throw new Error('mesh.bin: not a hivox mesh');
  const [nv, nt, flags] = new Uint32Array(buffer, 8, 4);
  let offset = 24;
  const take = (Type, count) => {
    const a = new Type(buffer, offset, count);
    offset += Math.ceil((count * Type.BYTES_PER_ELEMENT) / 4) * 4;
    return a;
  };
  const m = { nv, nt };
  m.positions = take(Float32Array, 3 * nv);
  if (flags & 1) m.normals = take(Float32Array, 3 * nv);
  if (flags & 2) m.colors = take(Uint8Array, 3 * nv);
  if (flags & 4) m.levels = take(Uint8Array, nv);
  m.indices = take(Uint32Array, 3 * nt);
  return m;
}

function hexToRgb(hex) {
  const v = parseInt(hex.slice(1), 16);
  return [(v >> 16) / 255, ((v >> 8) & 255) / 255, (v & 255) / 255];
}

// Per-vertex colours (0..1) for each mode.
function colorArray(mode, m, normals) {
  const out = new Float32Array(3 * m.nv);
  if (mode === 'rgb') {
    if (!m.colors) out.fill(0.75); else for (let i = 0; i < out.length; ++i) out[i] = m.colors[i] / 255;
  } else if (mode === 'level') {
    const table = viewer.info.level_colors.map(hexToRgb);
    for (let v = 0; v < m.nv; ++v) {
      const c = m.levels ? table[Math.min(m.levels[v], table.length - 1)] || [0.75, 0.75, 0.75] : [0.75, 0.75, 0.75];
      out.set(c, 3 * v);
    }
  } else {
    for (let i = 0; i < out.length; ++i) out[i] = 0.5 * (normals[i] + 1);
  }
  return out;
}

function setColor(mode) {
  if (mode === 'level' && !viewer.mesh.levels) mode = 'rgb';
  if (mode === 'rgb' && !viewer.mesh.colors && viewer.mesh.levels) mode = 'level';
  for (const r of document.querySelectorAll('input[name=color]')) r.checked = r.value === mode;
  const normals = viewer.geometry.getAttribute('normal').array;
  if (!viewer.colors[mode]) viewer.colors[mode] = colorArray(mode, viewer.mesh, normals);
  viewer.geometry.setAttribute('color', new THREE.BufferAttribute(viewer.colors[mode], 3));
  // Normals are shown unlit (their colour is the direction); the others under a headlight.
  viewer.object.material = mode === 'normal' ? viewer.unlit : viewer.lit;
  document.getElementById('legend').style.display = mode === 'level' ? 'flex' : 'none';
  document.body.dataset.color = mode;
  viewer.dirty = true;
}

function table(id, rows) {
  document.getElementById(id).replaceChildren(
    ...rows.filter(r => r[1] !== undefined && r[1] !== null && r[1] !== '').map(([k, v]) => hv.el('tr', {}, hv.el('td', {}, k), hv.el('td', {}, String(v)))));
}

function showInfo(info) {
  document.getElementById('path').textContent = `${info.kind}: ${info.path}`;
  table('mesh-info', [
    ['vertices', hv.count(info.vertices)],
    ['triangles', hv.count(info.triangles) + (info.triangles < info.source_triangles ? ` (decimated for display from ${hv.count(info.source_triangles)})` : '')],
    ['levels', info.levels || ''],
    ['size', info.bounds_m ? info.bounds_m[1].map((h, a) => (h - info.bounds_m[0][a]).toFixed(2)).join(' × ') + ' m' : ''],
  ]);
  hv.levelLegend(document.getElementById('legend'), info.level_colors, info.voxel_sizes_mm, info.vertices_per_level);
  const s = info.stats;
  if (s) {
    document.getElementById('run-section').hidden = false;
    const t = s.timing_ms || {};
    table('run-info', [
      ['dataset', s.dataset], ['frames', `${s.frames_fused} fused of ${s.frames}`],
      ['poses', s.poses], ['speed', s.fps ? `${s.fps.toFixed(1)} fps processing` : ''],
      ['blocks', s.blocks_per_level ? `${hv.count(s.blocks_total)} (${s.blocks_per_level.map(hv.count).join(' / ')})` : ''],
      ['memory', s.memory_bytes ? hv.bytes(s.memory_bytes) : ''],
      ['dropped', s.dropped_blocks ? hv.count(s.dropped_blocks) : ''],
      ['tracking', s.tracking ? `${s.tracking.good} good, ${s.tracking.poor} poor, ${s.tracking.lost} lost` : ''],
      ['ATE RMSE', s.ate_rmse_m !== undefined && s.ate_rmse_m !== null ? hv.length(s.ate_rmse_m) : ''],
      ['ms per frame', t.total ? ['track', 'allocate', 'integrate', 'refine', 'raycast'].map(k => `${k} ${(t[k] || 0).toFixed(1)}`).join(', ') : ''],
      ['version', s.hivox_version],
    ]);
  }
  if (info.images.length) {
    document.getElementById('images-section').hidden = false;
    document.getElementById('images').replaceChildren(...info.images.map(name =>
      hv.el('a', { href: `/files/${name}`, target: '_blank' }, hv.el('img', { src: `/files/${name}`, alt: name, loading: 'lazy' }), name)));
  }
}

function buildScene(info, m, trajectory) {
  const container = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0x15171b);
  container.append(renderer.domElement);
  const scene = new THREE.Scene();
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(m.positions, 3));
  geometry.setIndex(new THREE.BufferAttribute(m.indices, 1));
  if (m.normals) geometry.setAttribute('normal', new THREE.BufferAttribute(m.normals, 3));
  else geometry.computeVertexNormals();
  geometry.computeBoundingSphere();
  viewer.geometry = geometry;
  viewer.lit = new THREE.MeshLambertMaterial({ vertexColors: THREE.VertexColors, side: THREE.DoubleSide });
  viewer.unlit = new THREE.MeshBasicMaterial({ vertexColors: THREE.VertexColors, side: THREE.DoubleSide });
  viewer.object = new THREE.Mesh(geometry, viewer.lit);
  scene.add(viewer.object);
  scene.add(new THREE.AmbientLight(0xffffff, 0.35));
  const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
  const headlight = new THREE.DirectionalLight(0xffffff, 0.75);
  camera.add(headlight);
  scene.add(camera);

  if (trajectory.length > 1) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(trajectory.flat()), 3));
    viewer.trajectory = new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0x4fa3f7 }));
    scene.add(viewer.trajectory);
  }
  if (trajectory.length > 0) {
    const last = trajectory[trajectory.length - 1];
    const marker = new THREE.Mesh(new THREE.SphereGeometry(geometry.boundingSphere.radius * 0.015, 12, 8),
                                  new THREE.MeshBasicMaterial({ color: 0xffffff }));
    marker.position.set(...last);
    (viewer.trajectory || scene).add(marker);
    if (!viewer.trajectory) viewer.trajectory = marker;
  }
  document.getElementById('trajectory-info').textContent = trajectory.length ? `(${trajectory.length} poses)` : '(none)';

  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  const home = () => {
    const h = info.home;
    camera.up.set(...h.up);
    camera.position.set(...h.eye);
    controls.target.set(...h.target);
    camera.near = h.distance / 500; camera.far = h.distance * 50;
    camera.updateProjectionMatrix();
    controls.update();
    viewer.dirty = true;
  };
  home();
  controls.addEventListener('change', () => { viewer.dirty = true; });
  window.addEventListener('keydown', e => { if (e.key === 'r' || e.key === 'R') home(); });

  const resize = () => {
    const w = container.clientWidth, h = container.clientHeight;
    renderer.setSize(w, h);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    viewer.dirty = true;
  };
  window.addEventListener('resize', resize);
  resize();
  let frames = 0;
  const loop = () => {
    if (viewer.dirty) {
      viewer.dirty = false;
      renderer.render(scene, camera);
      if (++frames === 1) {
        const r = renderer.domElement.getBoundingClientRect();
        document.body.dataset.canvasRect = [r.left, r.top, r.width, r.height].map(Math.round).join(',');
        document.body.dataset.state = 'ready';
      }
    }
    requestAnimationFrame(loop);
  };
  loop();
}

async function main() {
  try {
    const [info, trajectory, buffer] = await Promise.all([
      hv.json('/api/info.json'), hv.json('/api/trajectory.json'),
      fetch('/api/mesh.bin').then(r => { if (!r.ok) throw new Error(`mesh.bin: ${r.status}`); return r.arrayBuffer(); })]);
    viewer.info = info;
    viewer.mesh = decodeMesh(buffer);
    showInfo(info);
    buildScene(info, viewer.mesh, trajectory);
    document.getElementById('loading').remove();
    for (const r of document.querySelectorAll('input[name=color]')) r.onchange = () => setColor(r.value);
    const show = document.getElementById('show-trajectory');
    show.checked = hv.params.get('trajectory') !== '0';
    show.onchange = () => { if (viewer.trajectory) viewer.trajectory.visible = show.checked; viewer.dirty = true; };
    show.onchange();
    setColor(hv.params.get('color') || (viewer.mesh.colors ? 'rgb' : 'level'));
  } catch (e) {
    document.getElementById('loading').textContent = `cannot show this: ${e.message}`;
    document.getElementById('loading').className = 'error';
    document.body.dataset.state = 'error';
  }
}

main();
