// tests/web/browser.mjs - the viewer of `loom serve` in a real browser:
// Debian's chromium (headless), driven by playwright-core from the build
// tree (it never downloads a browser).  Opens the page, waits for tiles,
// zooms in twice (once on the cloth, once by the API), changes a yarn's
// colour, asks for a render of the view, and saves screenshots for the
// shell test to measure (tests/cli/test_serve.sh).
//
//   node tests/web/browser.mjs URL OUTDIR
// Prints one JSON line of what it saw; exit 1 on a failure it can tell.
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { slow, newProfile, launch, firstPage } from './chromium.mjs';

const [url, out] = process.argv.slice(2);
const profile = newProfile();
const result = { ok: false };
let ctx;
const waitTiles = async (page, atLeast, ms) => {
  await page.waitForFunction((n) => window.loomStats && window.loomStats.tilesLoaded >= n,
                             atLeast, { timeout: ms });
  await page.waitForTimeout(800);  // let the animation settle
  // then until every tile the view needs is in (slow servers: sanitizers)
  await page.waitForFunction(() => {
    const item = window.loomViewer && window.loomViewer.world.getItemAt(0);
    return item && item.getFullyLoaded();
  }, null, { timeout: ms });
};
try {
  ctx = await launch(profile);
  const { page, errors } = await firstPage(ctx);
  await page.addInitScript(() => { window.loomRenderWidth = 160; });
  await page.goto(url, { waitUntil: 'load', timeout: 60000 * slow });
  await page.waitForFunction(() => window.loomStats && window.loomStats.ready, null,
                             { timeout: 60000 * slow });
  await waitTiles(page, 1, 60000 * slow);
  result.tiles_home = await page.evaluate(() => window.loomStats.tilesLoaded);
  await page.screenshot({ path: join(out, 'home.png') });
  // zoom on the cloth with the mouse wheel at its centre, then by the API
  const box = await page.locator('#cloth').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  for (let k = 0; k < 6; k++) await page.mouse.wheel(0, -300);
  await waitTiles(page, result.tiles_home + 1, 60000 * slow);
  // deeper, down to single fibres, by the viewer's own API
  await page.evaluate(() => {
    const v = window.loomViewer;
    v.viewport.zoomTo(v.viewport.getMaxZoom() / 2, null, true);
  });
  await waitTiles(page, result.tiles_home + 2, 60000 * slow);
  const n1 = await page.evaluate(() => window.loomStats.tilesLoaded);
  await page.waitForTimeout(1500);
  await page.screenshot({ path: join(out, 'zoom.png') });
  result.tiles_zoom = await page.evaluate(() => window.loomStats.tilesLoaded) - result.tiles_home;
  // recolour the first yarn bright green through the page's own input
  await page.evaluate(() => {
    const i = document.querySelector('#yarns input');
    i.value = '#00ff00';
    i.dispatchEvent(new Event('change'));
  });
  await page.waitForFunction(() => window.loomStats.version > 0, null, { timeout: 30000 * slow });
  await waitTiles(page, n1 + 1, 60000 * slow);
  await page.waitForTimeout(2000);
  await page.screenshot({ path: join(out, 'green.png') });
  // a render of the view
  await page.click('#render');
  await page.waitForFunction(() => !document.getElementById('render-panel').hidden &&
                             document.getElementById('render-img').complete &&
                             document.getElementById('render-img').naturalWidth > 0, null,
                             { timeout: 120000 * slow });
  result.render_width = await page.evaluate(() => document.getElementById('render-img').naturalWidth);
  await page.screenshot({ path: join(out, 'render.png') });
  result.failed_tiles = await page.evaluate(() => window.loomStats.tilesFailed);
  result.errors = errors;
  result.boxes = {
    cloth: await page.locator('#cloth').boundingBox(),
    drawdown: await page.locator('#drawdown').boundingBox(),
  };
  result.ok = errors.length === 0;
} catch (e) {
  result.error = String(e);
} finally {
  if (ctx) await ctx.close();
  rmSync(profile, { recursive: true, force: true });
}
console.log(JSON.stringify(result));
process.exit(result.ok ? 0 : 1);
