// tests/web/paint_weave.mjs - painting a weave with the paint tool of
// `loom serve`'s page in a real browser (Debian's chromium, headless,
// driven by playwright-core from the build tree): waits for the cloth,
// picks "weave", types WEAVE (a name or a draft of 0/1 rows) into the
// weave box, clicks "Paint a rectangle" and drags one over the middle of
// the cloth, then waits for the server's answer, the drawdown's painted
// patch and the new tiles.  The shell test (tests/cli/test_paint.sh)
// checks the paint file, the tiles and the drawdown against a fresh
// server over the saved file.
//
//   node tests/web/paint_weave.mjs URL OUTDIR WEAVE
// Prints one JSON line: the rectangle in cloth mm the page sent, the
// drawdown patches the page loaded; exit 1 on a failure it can tell.
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { slow, newProfile, launch, firstPage } from './chromium.mjs';

const [url, out, weave] = process.argv.slice(2);
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
  await page.waitForTimeout(500);
  result.patchesBefore = await page.evaluate(() => window.loomStats.patches);
  await page.selectOption('#paint-effect', 'weave');
  result.kindHidden = await page.locator('#paint-kind').isHidden();
  await page.fill('#paint-weave', weave);
  await page.click('#paint');
  const box = await page.locator('#cloth').boundingBox();
  await page.mouse.move(box.x + box.width * 0.40, box.y + box.height * 0.30);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.50, box.y + box.height * 0.45, { steps: 5 });
  await page.mouse.move(box.x + box.width * 0.58, box.y + box.height * 0.65, { steps: 5 });
  await page.mouse.up();
  await page.waitForFunction(() => window.loomStats.painted === 1 || window.loomStats.refused,
                             null, { timeout: 120000 * slow });
  result.refused = await page.evaluate(() => window.loomStats.refused || null);
  await page.waitForFunction(() => window.loomStats.patches >= 1, null,
                             { timeout: 60000 * slow });
  await page.waitForTimeout(500);
  await page.waitForFunction(loaded, null, { timeout: 120000 * slow });
  await page.waitForTimeout(1500);
  await page.screenshot({ path: join(out, 'woven.png') });
  result.mm = await page.evaluate(() => window.loomStats.paintedMM);
  result.patches = await page.evaluate(() => window.loomStats.patches);
  result.status = await page.evaluate(() => document.getElementById('status').textContent);
  result.errors = errors;
  result.ok = errors.length === 0 && !result.refused && result.kindHidden &&
              result.patchesBefore === 0 && result.patches === 1 &&
              Array.isArray(result.mm) && result.mm.length === 4;
} catch (e) {
  result.error = String(e);
} finally {
  if (ctx) await ctx.close();
  rmSync(profile, { recursive: true, force: true });
}
console.log(JSON.stringify(result));
process.exit(result.ok ? 0 : 1);
