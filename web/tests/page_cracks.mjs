// The crack test in the page's own pixels: Relief's page (GET /) on a `?background=` colour,
// without its HUD, flying `--poses` poses of the standard path (with the page's ?pitch=
// override from --query), screenshotted every `--every` ms into `--out-dir` while it flies.
// Prints one line of JSON: the screenshots and the page's counters; the Rust test counts the
// background pixels that terrain encloses.
//
//   node web/tests/page_cracks.mjs http://127.0.0.1:PORT --out-dir D [--poses 60]
//        [--every 300] [--width 480] [--height 270] [--query 'background=%23ff00ff&crack=none']

import { join } from 'node:path';
import { args, launch, report, within } from './browser.mjs';

const { base, options } = args();
const poses = Number(options.poses ?? 60);
const every = Number(options.every ?? 300);
const browser = await launch({
  width: Number(options.width ?? 480), height: Number(options.height ?? 270),
});
const { page } = browser;
let result;
try {
  const extra = options.query ? `&${options.query}` : '';
  await page.goto(`${base}/?path=standard&poses=${poses}&hud=0${extra}`);
  await within(60000, 'connecting', page.waitForFunction(
    () => window.relief && window.relief.connected && window.relief.triangles > 0,
    null, { polling: 100, timeout: 0 }));
  const shots = [];
  const deadline = Date.now() + poses * 100 + 90000;
  for (;;) {
    if (Date.now() > deadline) throw new Error('the flight did not end');
    const r = await page.evaluate(() => ({ ...window.relief }));
    const path = join(options['out-dir'], `shot-${shots.length}.png`);
    await page.screenshot({ path });
    shots.push({ path, pose: r.pathSent, tiles: r.tiles });
    if (r.pathSent >= poses && r.answered >= r.poseSeq && r.complete) break;
    await page.waitForTimeout(every);
  }
  const relief = await page.evaluate(() => JSON.parse(JSON.stringify(window.relief)));
  result = { ok: true, shots, relief, console: browser.console };
} catch (e) {
  result = { ok: false, error: e.message, console: browser.console };
} finally {
  await browser.close();
}
report(result);
