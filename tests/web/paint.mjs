// tests/web/paint.mjs - the paint tool of `loom serve`'s page in a real
// browser (Debian's chromium, headless, driven by playwright-core from the
// build tree): waits for the cloth, picks "stain" in a dark colour, clicks
// "Paint a rectangle" and drags one with the mouse over the middle of the
// cloth, then waits for the server's answer and the new tiles.  The shell
// test (tests/cli/test_paint.sh) checks the paint file and the tiles.
//
//   node tests/web/paint.mjs URL OUTDIR
// Prints one JSON line: the rectangle in cloth mm the page sent; exit 1 on
// a failure it can tell.
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { slow, newProfile, launch, firstPage } from './chromium.mjs';

const [url, out] = process.argv.slice(2);
const profile = newProfile();
const result = { ok: false };
let ctx;
const loaded = () => {
  const item = window.loomViewer && window.loomViewer.world.getItemAt(0);
  return item && item.getFullyLoaded();
};
try {
  ctx = await launch(profile);
  const { page, errors } = await firstPage(ctx);
  await page.goto(url, { waitUntil: 'load', timeout: 60000 * slow });
  await page.waitForFunction(() => window.loomStats && window.loomStats.ready, null,
                             { timeout: 60000 * slow });
  await page.waitForFunction(loaded, null, { timeout: 60000 * slow });
  await page.waitForTimeout(800);
  await page.selectOption('#paint-effect', 'stain');
  await page.evaluate(() => {
    const i = document.getElementById('paint-rgb');
    i.value = '#102040';
  });
  await page.click('#paint');
  const box = await page.locator('#cloth').boundingBox();
  await page.mouse.move(box.x + box.width * 0.40, box.y + box.height * 0.35);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.50, box.y + box.height * 0.45, { steps: 5 });
  await page.mouse.move(box.x + box.width * 0.55, box.y + box.height * 0.60, { steps: 5 });
  await page.mouse.up();
  await page.waitForFunction(() => window.loomStats.painted === 1, null,
                             { timeout: 60000 * slow });
  await page.waitForTimeout(500);
  await page.waitForFunction(loaded, null, { timeout: 60000 * slow });
  await page.waitForTimeout(1500);
  await page.screenshot({ path: join(out, 'painted.png') });
  await page.screenshot({ path: join(out, 'painted-close.png'), clip: {
    x: box.x + box.width * 0.3, y: box.y + box.height * 0.25,
    width: box.width * 0.35, height: box.height * 0.45 } });
  result.mm = await page.evaluate(() => window.loomStats.paintedMM);
  result.status = await page.evaluate(() => document.getElementById('status').textContent);
  result.errors = errors;
  result.ok = errors.length === 0 && Array.isArray(result.mm) && result.mm.length === 4;
} catch (e) {
  result.error = String(e);
} finally {
  if (ctx) await ctx.close();
  rmSync(profile, { recursive: true, force: true });
}
console.log(JSON.stringify(result));
process.exit(result.ok ? 0 : 1);
