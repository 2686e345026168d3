// Walks a camera path through a 3D Tiles export in the web viewer, in
// headless Chromium, and writes one CSV line per drawn frame: what a user
// of a 3D Tiles viewer would see on the same path as hlod-bench walks.
//
//   node walk.mjs URL --path path.txt --size 640x360 --fps 30 --out walk.csv [--timeout 3600]
//
// URL is the page with its parameters (error=, cache=). The path is a path
// file (hlod-bench writes path.txt). The walk first holds the path's first
// pose until the view is complete (the time to the first complete view),
// then plays the path in real time: the pose of each drawn frame is the
// one due at that moment, so a slow frame skips poses, as in a viewer.
// Columns: frame, pose, t_ms (since the walk began), complete (every tile
// the view selects is loaded), cached_bytes, downloaded_bytes,
// requests, visible_tiles, triangles.
import { readFileSync, writeFileSync } from 'node:fs';
import { commandLine, launch, untilComplete } from './browser.mjs';

const { url, opt } = commandLine();
const [w, h] = opt('size', '640x360').split('x').map(Number);
const fps = Number(opt('fps', '30'));
const out = opt('out', 'walk.csv');
const timeout = Number(opt('timeout', '3600')) * 1000;
const poses = readFileSync(opt('path'), 'utf8').split('\n')
  .map((l) => l.trim()).filter((l) => l && !l.startsWith('#'))
  .map((l) => l.split(/\s+/).map(Number));

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: w, height: h } });
  const t0 = Date.now();
  await page.goto(`${url}${url.includes('?') ? '&' : '?'}ui=0&camera=${poses[0].join(',')}`);
  const first = await untilComplete(page, timeout, 3);
  const firstMs = Date.now() - t0;
  const rows = await page.evaluate(async ([poses, fps]) => {
    const h = window.hlod;
    const frame = () => new Promise((r) => requestAnimationFrame(r));
    const rows = [];
    const start = performance.now();
    for (let n = 0; ; n++) {
      const t = performance.now() - start;
      const i = Math.floor((t / 1000) * fps);
      if (i >= poses.length) break;
      h.setPose(poses[i]);
      await frame();
      const s = h.stats();
      rows.push([n, i, Math.round(t), h.complete() ? 1 : 0, s.cachedBytes, s.downloaded, s.requests, s.visible, s.triangles]);
    }
    return rows;
  }, [poses, fps]);
  const head = 'frame,pose,t_ms,complete,cached_bytes,downloaded_bytes,requests,visible_tiles,triangles';
  writeFileSync(out, [head, ...rows.map((r) => r.join(','))].join('\n') + '\n');
  console.log(JSON.stringify({ firstCompleteMs: firstMs, first, frames: rows.length }));
} finally {
  await browser.close();
}
