// Shared by the browser test scripts: headless Chromium (Debian's `chromium`) driven by
// playwright-core, a log of every request the pages make, deterministic test points, and the
// one-line JSON result the Rust tests read.

import { mkdtempSync, rmSync, existsSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

/** Debian's Chromium, or $RELIEF_CHROMIUM. */
export const CHROMIUM = process.env.RELIEF_CHROMIUM || '/usr/bin/chromium';

/** The flags: new headless mode, software WebGL (SwiftShader), nothing in the background. */
export const FLAGS = [
  '--headless=new',
  '--no-sandbox',
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
];

/** Prints why the test cannot run and how to fix it, and exits 2. */
export function missing(what) {
  process.stderr.write(`${what}\nInstall what the browser tests need (as root): ` +
    'apt-get install -y chromium && npm ci --prefix web (the README\'s test command does both).\n');
  process.exit(2);
}

/** The arguments: the server URL first, then `--name value` options. */
export function args() {
  const [url, ...rest] = process.argv.slice(2);
  if (!url || !/^http:\/\/(127\.0\.0\.1|localhost)(:\d+)?\/?$/.test(url)) {
    process.stderr.write('usage: node <script> http://127.0.0.1:PORT [--option value ...]\n');
    process.exit(2);
  }
  const options = {};
  for (let i = 0; i < rest.length; i += 2) {
    options[rest[i].replace(/^--/, '')] = rest[i + 1];
  }
  return { base: url.replace(/\/$/, ''), options };
}

/**
 * Chromium with a fresh profile and one page of `width` x `height`; every request of the
 * context (pages and their workers) goes into `requests`; `touch` gives it a touch screen.
 * `close()` ends it and removes the profile.
 */
export async function launch({ width = 960, height = 600, touch = false } = {}) {
  if (!existsSync(CHROMIUM)) missing(`Chromium is not at ${CHROMIUM}.`);
  let chromium;
  try {
    ({ chromium } = await import('playwright-core'));
  } catch (e) {
    missing(`playwright-core is not installed (${e.message}).`);
  }
  const profile = mkdtempSync(join(tmpdir(), 'relief-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    args: FLAGS,
    viewport: { width, height },
    deviceScaleFactor: 1,
    hasTouch: touch,
  });
  const requests = [];
  context.on('request', (r) => requests.push(r.url()));
  const page = context.pages()[0] ?? await context.newPage();
  const consoleLines = [];
  page.on('console', (m) => consoleLines.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => consoleLines.push(`pageerror: ${e.message}`));
  return {
    context,
    page,
    requests,
    console: consoleLines,
    async close() {
      await context.close();
      rmSync(profile, { recursive: true, force: true });
    },
  };
}

/** Of `urls`, those on a host other than 127.0.0.1 or localhost (data: and blob: are local). */
export function foreign(urls) {
  return urls.filter((u) => {
    const url = new URL(u);
    if (url.protocol === 'data:' || url.protocol === 'blob:') return false;
    return !['127.0.0.1', 'localhost', '[::1]'].includes(url.hostname);
  });
}

/**
 * `n` points inside the box [w, s, e, n], `margin` (a fraction of each side) in from its
 * edges, from a fixed seed: the same points on every run.
 */
export function points(bounds, n, margin = 0.02, seed = 0x5eed) {
  const [w, s, e, nn] = bounds;
  let state = seed >>> 0;
  const random = () => {
    // xorshift32
    state ^= state << 13;
    state >>>= 0;
    state ^= state >>> 17;
    state ^= state << 5;
    state >>>= 0;
    return state / 0x100000000;
  };
  const out = [];
  for (let i = 0; i < n; i++) {
    const fx = margin + (1 - 2 * margin) * random();
    const fy = margin + (1 - 2 * margin) * random();
    out.push([w + (e - w) * fx, s + (nn - s) * fy]);
  }
  return out;
}

/** Waits for `promise`, or fails after `ms` with `what`. */
export function within(ms, what, promise) {
  let timer;
  return Promise.race([
    promise.finally(() => clearTimeout(timer)),
    new Promise((_, reject) => {
      timer = setTimeout(() => reject(new Error(`${what} took over ${ms / 1000} s`)), ms);
    }),
  ]);
}

/** Prints the result as one line of JSON on stdout, the line the Rust test parses. */
export function report(result) {
  process.stdout.write(`${JSON.stringify(result)}\n`);
}

/**
 * Opens `path` of the server in a fresh browser, waits up to `ms` for the page's
 * `window.relief.ready` (`what` names the wait in a timeout), then runs `body(page)` for the
 * rest of the result, and prints one line of JSON: `ok`, `ready`, `loaded_ms`, what `body`
 * returned, `total_ms`, the request log and the console; or `ok: false` with the error (and
 * what the page says), the request log and the console.
 */
export async function runPage(base, path, ms, what, body) {
  const started = Date.now();
  const browser = await launch({ width: 960, height: 600 });
  const { page } = browser;
  let result;
  try {
    await page.goto(`${base}${path}`);
    const ready = await within(ms, what, page.evaluate(async () => {
      if (!window.relief) throw new Error('the page has no window.relief');
      return window.relief.ready;
    }));
    const loaded = Date.now() - started;
    const rest = await body(page);
    result = {
      ok: true,
      ready,
      loaded_ms: loaded,
      ...rest,
      total_ms: Date.now() - started,
      requests: browser.requests,
      console: browser.console,
    };
  } catch (e) {
    const error = await page.evaluate(() => window.relief?.error).catch(() => null);
    result = {
      ok: false,
      error: `${e.message}${error ? ` (the page says: ${error})` : ''}`,
      requests: browser.requests,
      console: browser.console,
    };
  } finally {
    await browser.close();
  }
  report(result);
}
