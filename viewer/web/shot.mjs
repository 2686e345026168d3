// Drives the web viewer in headless Chromium (playwright-core): opens URL,
// waits until every tile the view asks for is loaded and drawn, saves a
// screenshot, optionally picks at a pixel, and prints what it saw as JSON.
//
//   node shot.mjs URL --size 640x480 --out shot.png [--pick X,Y;X,Y...] [--click X,Y] [--timeout 120]
//
// Chromium and the wait are browser.mjs's.
import { commandLine, launch, untilComplete } from './browser.mjs';

const { url, opt } = commandLine();
const [w, h] = opt('size', '640x480').split('x').map(Number);
const out = opt('out', null);
const pickAt = opt('pick', null);
const timeout = Number(opt('timeout', '120')) * 1000;

const browser = await launch();
const errors = [];
try {
  const page = await browser.newPage({ viewport: { width: w, height: h } });
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  const t0 = Date.now();
  await page.goto(url);
  await untilComplete(page, timeout, 5);
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
