// Relief's page across a server restart: loads GET / (with `--query`, e.g. `stream=vertex`),
// waits until terrain is drawn, then writes
// `--ready-file` so that the test kills the server; records every change of the page's
// connection state (connected, the message it shows, reconnects, resumes, desyncs) until the
// test writes `--stop-file` (after restarting the server) and the page is connected again, and
// prints them as one line of JSON.
//
//   node web/tests/page_restart.mjs http://127.0.0.1:PORT --ready-file F --stop-file G
//        [--query 'stream=vertex']

import { existsSync, writeFileSync } from 'node:fs';
import { args, launch, report, within } from './browser.mjs';

const { base, options } = args();
const browser = await launch({ width: 640, height: 400 });
const { page } = browser;
let result;
try {
  await page.goto(`${base}/${options.query ? `?${options.query}` : ''}`);
  await within(60000, 'connecting', page.waitForFunction(
    () => window.relief && window.relief.deltas > 0 && window.relief.triangles > 0,
    null, { polling: 100, timeout: 0 }));
  writeFileSync(options['ready-file'], 'ready');
  const states = [];
  const deadline = Date.now() + 90000;
  for (;;) {
    if (Date.now() > deadline) throw new Error('the page did not reconnect within 90 s');
    const r = await page.evaluate(() => {
      const x = window.relief;
      return {
        connected: x.connected, message: x.message, reconnects: x.reconnects,
        resumes: x.resumes, desyncs: x.desyncs, welcomes: x.welcomes, tiles: x.tiles,
        triangles: x.triangles, deltas: x.deltas,
      };
    });
    const last = states[states.length - 1];
    const key = (s) => JSON.stringify({ ...s, deltas: 0 });
    if (!last || key(last) !== key(r)) states.push(r);
    if (existsSync(options['stop-file']) && r.connected && r.resumes > 0) break;
    await page.waitForTimeout(100);
  }
  result = { ok: true, states, console: browser.console };
} catch (e) {
  result = { ok: false, error: e.message, console: browser.console };
} finally {
  await browser.close();
}
report(result);
