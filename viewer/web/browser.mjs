// What shot.mjs and walk.mjs share: their command line, Debian's Chromium
// (/usr/bin/chromium, or $CHROMIUM) headless with WebGL through SwiftShader
// (so it runs without a GPU), and the wait for a complete view.
import { chromium } from 'playwright-core';

// The URL (first argument) and `opt(name, default)` for `--name value`.
export function commandLine() {
  const args = process.argv.slice(2);
  const opt = (name, dflt) => {
    const i = args.indexOf(`--${name}`);
    return i >= 0 ? args[i + 1] : dflt;
  };
  return { url: args[0], opt };
}

export function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--no-first-run', '--disable-quic'],
  });
}

// Draws frames until the page's view has been complete (nothing loading,
// every selected tile loaded) on `calm` frames in a row; throws, with the
// page's figures, if that takes over `timeoutMs`. Returns those figures.
export async function untilComplete(page, timeoutMs, calm) {
  await page.waitForFunction(() => window.hlod !== undefined, null, { timeout: timeoutMs });
  const r = await page.evaluate(async ([calm, timeoutMs]) => {
    const h = window.hlod;
    const frame = () => new Promise((done) => requestAnimationFrame(done));
    const deadline = performance.now() + timeoutMs;
    for (let n = 0; n < calm;) {
      if (performance.now() > deadline) return { done: false, stats: h.stats() };
      await frame();
      n = h.idle() && h.complete() ? n + 1 : 0;
    }
    return { done: true, stats: h.stats() };
  }, [calm, timeoutMs]);
  if (!r.done) throw new Error(`view not complete after ${timeoutMs} ms: ${JSON.stringify(r.stats)}`);
  return r.stats;
}
