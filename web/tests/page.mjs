// Relief's own page (GET /) in headless Chromium: flies the first `--poses` poses of the
// standard camera path at 10 Hz over a tile session (or, with `--path none`, holds the page's
// start view), waits until the server has answered the last pose completely, measures the
// frame rate for `--fps-seconds`, takes a screenshot, and prints one line of JSON: the page's
// counters (window.relief), fps, the console and the request log.
//
//   node web/tests/page.mjs http://127.0.0.1:PORT [--poses 100] [--path standard|none]
//        [--screenshot out.png] [--width 1280] [--height 720] [--fps-seconds 3]
//        [--query 'crack=none&...']

import { args, launch, report, within } from './browser.mjs';

const { base, options } = args();
const poses = Number(options.poses ?? 100);
const width = Number(options.width ?? 1280);
const height = Number(options.height ?? 720);
const fpsSeconds = Number(options['fps-seconds'] ?? 3);
const pathKind = options.path ?? 'standard';
const started = Date.now();
const browser = await launch({ width, height });
const { page } = browser;
let result;
try {
  const extra = options.query ? `&${options.query}` : '';
  const flight = pathKind === 'none' ? '' : `path=${pathKind}&poses=${poses}`;
  await page.goto(`${base}/?${flight}${extra}`);
  await within(60000, 'connecting', page.waitForFunction(
    () => window.relief && window.relief.connected && window.relief.deltas > 0,
    null, { polling: 100, timeout: 0 }));
  const connected_ms = Date.now() - started;
  const bytesAtStart = await page.evaluate(() => window.relief.bytes);
  // The flight: `poses` poses at 10 Hz (none when holding the start view), then the answer to
  // the last one, complete.
  const n = flight ? poses : 0;
  await within(n * 100 + 90000, 'flying the path', page.waitForFunction(
    (n) => {
      const r = window.relief;
      return r.pathSent >= n && r.poseSeq > 0 && r.answered >= r.poseSeq && r.complete;
    },
    n, { polling: 100, timeout: 0 }));
  const flown_ms = Date.now() - started;
  const bytesAtEnd = await page.evaluate(() => window.relief.bytes);
  const before = await page.evaluate(() => ({ frames: window.relief.frames, t: performance.now() }));
  await page.waitForTimeout(fpsSeconds * 1000);
  const after = await page.evaluate(() => ({ frames: window.relief.frames, t: performance.now() }));
  const fps = (1000 * (after.frames - before.frames)) / (after.t - before.t);
  if (options.screenshot) await page.screenshot({ path: options.screenshot });
  const relief = await page.evaluate(() => JSON.parse(JSON.stringify(window.relief)));
  result = {
    ok: true,
    relief,
    fps,
    flight_bytes_per_s: (1000 * (bytesAtEnd - bytesAtStart)) / Math.max(1, flown_ms - connected_ms),
    connected_ms,
    flown_ms,
    total_ms: Date.now() - started,
    viewport: [width, height],
    requests: browser.requests,
    console: browser.console,
    screenshot: options.screenshot ?? null,
  };
} catch (e) {
  const relief = await page.evaluate(() => JSON.parse(JSON.stringify(window.relief ?? null)))
    .catch(() => null);
  result = {
    ok: false,
    error: `${e.message}; the page's counters: ${JSON.stringify(relief)}`,
    requests: browser.requests,
    console: browser.console,
  };
} finally {
  await browser.close();
}
report(result);
