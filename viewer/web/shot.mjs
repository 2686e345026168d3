// Drives the web viewer in headless Chromium (playwright-core): opens URL,
// waits until every tile the view asks for is loaded and drawn, saves a
// screenshot, optionally picks at a pixel, and prints what it saw as JSON.
//
//   node shot.mjs URL --size 640x480 --out shot.png [--pick X,Y;X,Y...] [--click X,Y] [--timeout 120]
//
// Chromium is Debian's (/usr/bin/chromium, or $CHROMIUM), with WebGL through
// SwiftShader, so it runs without a GPU.
import { chromium } from 'playwright-core';

const args = process.argv.slice(2);
const url = args[0];
const opt = (name, dflt) => {
  const i = args.indexOf(`--${name}`);
  return i >= 0 ? args[i + 1] : dflt;
};
const [w, h] = opt('size', '640x480').split('x').map(Number);
const out = opt('out', null);
const pickAt = opt('pick', null);
const timeout = Number(opt('timeout', '120')) * 1000;

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--no-first-run', '--disable-quic'],
});
const errors = [];
try {
  const page = await browser.newPage({ viewport: { width: w, height: h } });
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  const t0 = Date.now();
  await page.goto(url);
  await page.waitForFunction(() => window.hlod !== undefined, null, { timeout });
  // Idle on several checks in a row, frames drawn between them.
  let calm = 0;
  while (calm < 5) {
    if (Date.now() - t0 > timeout) throw new Error(`not idle after ${timeout} ms: ${JSON.stringify(await page.evaluate(() => window.hlod.stats()))}`);
    const f0 = await page.evaluate(() => window.hlod.frames());
    await page.waitForFunction((f) => window.hlod.frames() > f + 1, f0, { timeout });
    calm = (await page.evaluate(() => window.hlod.idle() && window.hlod.complete())) ? calm + 1 : 0;
  }
  const idleMs = Date.now() - t0;
  const click = opt('click', null);
  if (click) {
    const [x, y] = click.split(',').map(Number);
    await page.mouse.click(x, y);
    const f = await page.evaluate(() => window.hlod.frames());
    await page.waitForFunction((f) => window.hlod.frames() > f + 1, f, { timeout });
  }
  if (out) await page.screenshot({ path: out });
  const stats = await page.evaluate(() => window.hlod.stats());
  const pick = [];
  for (const at of pickAt ? pickAt.split(';') : []) {
    const [x, y] = at.split(',').map(Number);
    pick.push(await page.evaluate(([x, y]) => window.hlod.pick(x, y), [x, y]));
  }
  console.log(JSON.stringify({ idleMs, stats, pick, errors }));
} finally {
  await browser.close();
}
