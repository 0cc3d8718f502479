// Relief's page (GET /) on a touch screen: one finger dragged across the view turns the camera
// (yaw) and up the view tilts it (pitch); two fingers held fly it forward. Touches are sent as
// the browser's own touch input (Chrome DevTools Protocol `Input.dispatchTouchEvent`), which
// Chromium turns into the pointer events the page listens to. Prints one line of JSON: the
// camera before and after each gesture, and the page's counters.
//
//   node web/tests/page_touch.mjs http://127.0.0.1:PORT

import { args, launch, report, within } from './browser.mjs';

const { base } = args();
const browser = await launch({ width: 800, height: 450, touch: true });
const { page } = browser;
let result;
try {
  await page.goto(`${base}/?hud=0`);
  await within(60000, 'connecting', page.waitForFunction(
    () => window.relief && window.relief.connected && window.relief.deltas > 0,
    null, { polling: 100, timeout: 0 }));
  const cdp = await page.context().newCDPSession(page);
  const camera = () => page.evaluate(() => ({ ...window.relief.camera }));
  const touch = (type, points) => cdp.send('Input.dispatchTouchEvent', {
    type, touchPoints: points.map(([x, y], id) => ({ x, y, id })),
  });
  // One finger along a line, in steps, as a real drag arrives.
  const drag = async (from, to, steps = 10) => {
    await touch('touchStart', [from]);
    for (let i = 1; i <= steps; i++) {
      const t = i / steps;
      await touch('touchMove', [[from[0] + t * (to[0] - from[0]), from[1] + t * (to[1] - from[1])]]);
    }
    await touch('touchEnd', []);
  };
  const start = await camera();
  const posesStart = await page.evaluate(() => window.relief.poses);
  await drag([300, 220], [400, 220]);
  const turned = await camera();
  await drag([400, 260], [400, 210]);
  const tilted = await camera();
  await touch('touchStart', [[300, 200], [500, 200]]);
  await page.waitForTimeout(1000);
  await touch('touchEnd', []);
  const flown = await camera();
  await within(30000, 'the answer to the last pose', page.waitForFunction(
    () => window.relief.answered >= window.relief.poseSeq && window.relief.complete,
    null, { polling: 100, timeout: 0 }));
  const relief = await page.evaluate(() => JSON.parse(JSON.stringify(window.relief)));
  result = {
    ok: true, start, turned, tilted, flown, poses_start: posesStart, relief,
    console: browser.console,
  };
} catch (e) {
  result = { ok: false, error: e.message, console: browser.console };
} finally {
  await browser.close();
}
report(result);
