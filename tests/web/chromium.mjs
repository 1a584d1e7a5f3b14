// tests/web/chromium.mjs - what the browser tests share: Debian's chromium
// (headless), driven by playwright-core from the build tree (it never
// downloads a browser), in a throw-away profile directory.
import { createRequire } from 'node:module';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

// sanitizer builds make tiles 5-15x slower: wait longer, check the same
export const slow = process.env.LOOM_SAN ? 5 : 1;

// A fresh profile directory (the caller removes it).
export const newProfile = () => mkdtempSync(join(tmpdir(), 'loom-chromium-'));

// Chromium over profile, 1200 x 700, nothing fetched in the background.
export async function launch(profile) {
  const require = createRequire(join(process.env.LOOM_BUILD, 'web', 'package.json'));
  const { chromium } = require('playwright-core');
  return chromium.launchPersistentContext(profile, {
    executablePath: '/usr/bin/chromium',
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
           '--disable-background-networking', '--disable-component-update', '--disable-sync'],
    viewport: { width: 1200, height: 700 },
  });
}

// The context's page and the page errors it reports from now on.
export async function firstPage(ctx) {
  const page = ctx.pages()[0] || await ctx.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  return { page, errors };
}
