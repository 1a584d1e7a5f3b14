/*
 * tools/web/viewer.js - the page of `loom serve`: the cloth as a deep-zoom
 * picture (OpenSeadragon over the server's /tile/L/X/Y.png pyramid), the
 * colour drawdown beside it drawn on a canvas for exactly the region the
 * cloth shows (one repeat from /drawdown.png, tiled as a canvas pattern,
 * and the painted weaves' crossings from /painted/K.png over it),
 * yarn colours editable (POST /api/color; tiles are re-made in the new
 * colours without new synthesis), and a render of the view
 * (/api/render), and a paint tool: a rectangle dragged on the cloth (in
 * cloth millimetres) becomes a painted region of colour, defect or weave
 * (a weave name or a draft of 0/1 rows), saved by the server in the paint
 * file (POST /api/paint) and shown at once, a weave in the drawdown too.
 * window.loomStats counts tiles and paints for the browser tests.
 */
'use strict';
window.loomStats = { tilesLoaded: 0, tilesFailed: 0, ready: false, version: 0 };

(async function main() {
  const status = document.getElementById('status');
  const info = await (await fetch('/api/info')).json();
  let version = info.version;
  document.getElementById('title').textContent =
    `loom: ${info.design[0]} picks x ${info.design[1]} ends, ` +
    `${info.repeats[0]} x ${info.repeats[1]} repeats`;

  const clothSource = () => ({
    width: info.width, height: info.height, tileSize: info.tile_size,
    tileOverlap: 0, minLevel: 0, maxLevel: info.max_level,
    getTileUrl: (l, x, y) => `/tile/${l}/${x}/${y}.png?v=${version}`,
  });
  const cloth = OpenSeadragon({
    id: 'cloth', prefixUrl: '/images/', tileSources: clothSource(),
    showNavigator: true, navigatorPosition: 'BOTTOM_RIGHT',
    maxZoomPixelRatio: 4, visibilityRatio: 0.5, imageLoaderLimit: 4,
    timeout: 120000, animationTime: 0.6,
  });
  window.loomViewer = cloth;
  cloth.addHandler('tile-loaded', () => { window.loomStats.tilesLoaded++; });
  cloth.addHandler('tile-load-failed', () => { window.loomStats.tilesFailed++; });
  cloth.addHandler('open', () => { window.loomStats.ready = true; });

  /* voxels of the window: picture pixels / pixels_per_voxel */
  const ppv = info.pixels_per_voxel;
  const view = () => {
    const b = cloth.viewport.getBounds(true);   /* x, y in picture widths */
    const k = info.width / ppv;                  /* voxels per picture width */
    return { x0: b.x * k, y0: b.y * k, x1: (b.x + b.width) * k, y1: (b.y + b.height) * k };
  };

  /* the drawdown: the same region, cell per crossing */
  const canvas = document.getElementById('drawdown');
  const ctx = canvas.getContext('2d');
  let repeat = null;
  let patches = [];  /* painted weaves: [I0, J0, rows, cols] and their picture */
  const loadImage = (src) => new Promise((ok) => {
    const img = new Image();
    img.onload = () => ok(img);
    img.onerror = () => ok(null);
    img.src = src;
  });
  const loadDrawdown = async () => {
    repeat = await loadImage(`/drawdown.png?v=${version}`);
    const pw = info.painted_weaves || [];
    patches = await Promise.all(pw.map(async (p, k) => ({
      at: p, img: await loadImage(`/painted/${k}.png?v=${version}`) })));
    window.loomStats.patches = patches.filter((p) => p.img).length;
  };
  const drawDrawdown = () => {
    const el = document.getElementById('cloth');
    canvas.width = canvas.clientWidth;
    canvas.height = Math.max(1, Math.round(canvas.width * el.clientHeight / el.clientWidth));
    if (!repeat) return;
    const v = view();
    const cx0 = v.x0 / info.block[0], cy0 = v.y0 / info.block[1];
    const sx = canvas.width / ((v.x1 - v.x0) / info.block[0]);
    const sy = canvas.height / ((v.y1 - v.y0) / info.block[1]);
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = '#050505';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    /* minified, the repeat is first scaled down with the browser's good
       filter (a pattern alone would sample it and alias); magnified, cells
       stay crisp */
    let src = repeat;
    if (sx < 1 || sy < 1) {
      const off = document.createElement('canvas');
      off.width = Math.max(1, Math.round(repeat.width * Math.min(1, sx)));
      off.height = Math.max(1, Math.round(repeat.height * Math.min(1, sy)));
      const o = off.getContext('2d');
      o.imageSmoothingEnabled = true;
      o.imageSmoothingQuality = 'high';
      o.drawImage(repeat, 0, 0, off.width, off.height);
      src = off;
    }
    ctx.imageSmoothingEnabled = src !== repeat;
    const pattern = ctx.createPattern(src, 'repeat');
    if (src !== repeat)   /* pattern pixels back to crossing units */
      pattern.setTransform(new DOMMatrix([repeat.width / src.width, 0, 0,
                                          repeat.height / src.height, 0, 0]));
    ctx.setTransform(sx, 0, 0, sy, -cx0 * sx, -cy0 * sy);
    ctx.fillStyle = pattern;
    /* the window only: repeats x repeats of the design */
    const x0 = Math.max(0, cx0), y0 = Math.max(0, cy0);
    const x1 = Math.min(info.design[1] * info.repeats[0], v.x1 / info.block[0]);
    const y1 = Math.min(info.design[0] * info.repeats[1], v.y1 / info.block[1]);
    if (x1 > x0 && y1 > y0) ctx.fillRect(x0, y0, x1 - x0, y1 - y0);
    /* painted weaves over the repeat, crossing for crossing */
    ctx.imageSmoothingEnabled = sx < 1 || sy < 1;
    for (const p of patches)
      if (p.img) ctx.drawImage(p.img, p.at[1], p.at[0], p.at[3], p.at[2]);
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    const mm = (v.x1 - v.x0) * info.voxel_um / 1000;
    document.getElementById('scale').textContent = `${mm.toFixed(mm < 10 ? 2 : 1)} mm across`;
  };
  cloth.addHandler('animation', drawDrawdown);
  cloth.addHandler('open', drawDrawdown);
  cloth.addHandler('resize', drawDrawdown);
  window.addEventListener('resize', drawDrawdown);
  /* dragging and wheeling the drawdown moves the cloth too */
  let drag = null;
  canvas.addEventListener('mousedown', (e) => { drag = { x: e.clientX, y: e.clientY }; });
  window.addEventListener('mouseup', () => { drag = null; });
  window.addEventListener('mousemove', (e) => {
    if (!drag) return;
    const b = cloth.viewport.getBounds(true);
    const dx = (e.clientX - drag.x) / canvas.clientWidth * b.width;
    const dy = (e.clientY - drag.y) / canvas.clientHeight * b.height;
    cloth.viewport.panBy(new OpenSeadragon.Point(-dx, -dy), true);
    drag = { x: e.clientX, y: e.clientY };
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    cloth.viewport.zoomBy(e.deltaY < 0 ? 1.25 : 0.8);
  }, { passive: false });
  await loadDrawdown();
  drawDrawdown();

  /* yarn colours */
  const yarns = document.getElementById('yarns');
  info.yarns.forEach((y) => {
    const label = document.createElement('label');
    const input = document.createElement('input');
    input.type = 'color';
    input.value = y.rgb;
    input.dataset.type = y.id;
    input.title = y.name;
    input.addEventListener('change', async () => {
      status.textContent = `recolouring ${y.name}...`;
      const r = await fetch(`/api/color?type=${y.id}&rgb=${input.value.slice(1)}`,
                            { method: 'POST' });
      if (!r.ok) { status.textContent = `colour refused (${r.status})`; return; }
      version = (await r.json()).version;
      window.loomStats.version = version;
      const keep = cloth.viewport.getBounds(true);
      cloth.addTiledImage({
        tileSource: clothSource(), index: 0, replace: true,
        success: () => { cloth.viewport.fitBounds(keep, true); drawDrawdown(); },
      });
      await loadDrawdown();
      drawDrawdown();
      status.textContent = `${y.name} is now ${input.value}`;
    });
    label.appendChild(input);
    label.appendChild(document.createTextNode(y.name));
    yarns.appendChild(label);
  });

  /* the paint tool: drag a rectangle on the cloth */
  const clothEl = document.getElementById('cloth');
  const paintBox = document.getElementById('paint-box');
  const paintBtn = document.getElementById('paint');
  let painting = false, from = null;
  const setPainting = (on) => {
    painting = on;
    cloth.setMouseNavEnabled(!on);
    clothEl.classList.toggle('painting', on);
    paintBtn.textContent = on ? 'Cancel painting' : 'Paint a rectangle';
    status.textContent = on ? 'drag a rectangle on the cloth' : status.textContent;
  };
  paintBtn.onclick = () => setPainting(!painting);
  /* a weave has no yarn kind or colour: its name or draft instead */
  const effectEl = document.getElementById('paint-effect');
  const weaveEl = document.getElementById('paint-weave');
  const showEffect = () => {
    const w = effectEl.value === 'weave';
    weaveEl.hidden = !w;
    document.getElementById('paint-kind').hidden = w;
    document.getElementById('paint-rgb').hidden = w;
  };
  effectEl.addEventListener('change', showEffect);
  showEffect();
  const local = (e) => {
    const r = clothEl.getBoundingClientRect();
    return { x: e.clientX - r.left, y: e.clientY - r.top };
  };
  const toMM = (p) => {   /* viewport units are picture widths on both axes */
    const v = cloth.viewport.pointFromPixel(new OpenSeadragon.Point(p.x, p.y), true);
    const k = info.width / ppv * info.voxel_um / 1000;
    return { x: v.x * k, y: v.y * k };
  };
  const showBox = (a, b) => {
    paintBox.hidden = false;
    paintBox.style.left = `${Math.min(a.x, b.x)}px`;
    paintBox.style.top = `${Math.min(a.y, b.y)}px`;
    paintBox.style.width = `${Math.abs(b.x - a.x)}px`;
    paintBox.style.height = `${Math.abs(b.y - a.y)}px`;
  };
  clothEl.addEventListener('pointerdown', (e) => {
    if (!painting) return;
    e.preventDefault();
    e.stopPropagation();
    from = local(e);
    showBox(from, from);
  }, true);
  window.addEventListener('pointermove', (e) => { if (from) showBox(from, local(e)); }, true);
  window.addEventListener('pointerup', async (e) => {
    if (!from) return;
    const to = local(e), a = toMM(from), b = toMM(to);
    from = null;
    paintBox.hidden = true;
    setPainting(false);
    if (Math.abs(b.x - a.x) < 1e-3 || Math.abs(b.y - a.y) < 1e-3) return;
    const q = new URLSearchParams({
      x0: Math.min(a.x, b.x).toFixed(4), y0: Math.min(a.y, b.y).toFixed(4),
      x1: Math.max(a.x, b.x).toFixed(4), y1: Math.max(a.y, b.y).toFixed(4),
      effect: effectEl.value });
    if (effectEl.value === 'weave') {
      const w = weaveEl.value.trim();
      q.set(/^[01]+(\/[01]+)*$/.test(w) ? 'draft' : 'weave', w);
    } else {
      q.set('kind', document.getElementById('paint-kind').value);
      q.set('rgb', document.getElementById('paint-rgb').value.slice(1));
    }
    status.textContent = effectEl.value === 'weave' ? 'weaving...' : 'painting...';
    const r = await fetch(`/api/paint?${q}`, { method: 'POST' });
    if (!r.ok) {
      let why = await r.text();
      try { why = JSON.parse(why).message; } catch (e) { /* the text as it is */ }
      status.textContent = `paint refused: ${why}`;
      window.loomStats.refused = why;
      return;
    }
    version = (await r.json()).version;
    if (effectEl.value === 'weave') {
      /* the painted weaves' crossings: the drawdown draws them */
      info.painted_weaves = (await (await fetch('/api/info')).json()).painted_weaves;
      await loadDrawdown();
      drawDrawdown();
    }
    window.loomStats.version = version;
    window.loomStats.painted = (window.loomStats.painted || 0) + 1;
    window.loomStats.paintedMM = [q.get('x0'), q.get('y0'), q.get('x1'), q.get('y1')].map(Number);
    const keep = cloth.viewport.getBounds(true);
    cloth.addTiledImage({
      tileSource: clothSource(), index: 0, replace: true,
      success: () => { cloth.viewport.fitBounds(keep, true); drawDrawdown(); },
    });
    status.textContent = `painted ${q.get('weave') || q.get('draft') || q.get('effect')} (saved)`;
  }, true);

  /* a render of the view */
  const panel = document.getElementById('render-panel');
  document.getElementById('close-render').onclick = () => { panel.hidden = true; };
  document.getElementById('render').onclick = async () => {
    const v = view();
    const wx = info.window_voxels[0], wy = info.window_voxels[1];
    const clamp = (t) => Math.min(1, Math.max(0, t));
    const q = `x0=${clamp(v.x0 / wx)}&y0=${clamp(v.y0 / wy)}&x1=${clamp(v.x1 / wx)}` +
              `&y1=${clamp(v.y1 / wy)}&w=${window.loomRenderWidth || 320}`;
    status.textContent = 'rendering the view...';
    const t0 = performance.now();
    const r = await fetch(`/api/render?${q}`);
    if (!r.ok) { status.textContent = `render refused (${r.status})`; return; }
    const url = URL.createObjectURL(await r.blob());
    document.getElementById('render-img').src = url;
    panel.hidden = false;
    status.textContent = `rendered in ${((performance.now() - t0) / 1000).toFixed(1)} s`;
  };
  status.textContent = 'drag to pan, wheel to zoom';
})().catch((e) => {
  document.getElementById('status').textContent = `error: ${e}`;
  window.loomStats.error = String(e);
});
