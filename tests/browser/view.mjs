// Drives the page of `cleave view` in headless Chromium (Debian's; playwright-core
// downloads no browser). Run by tests/viewer.rs:
//   node view.mjs check URL OUT_DIR   the page draws, a stroke cuts, a grab drags, a
//                                     second page sees the same simulation, pause
//                                     stops the frames, bad messages are survived,
//                                     the scene picker runs a scene's own tools
//   node view.mjs stopped URL OUT_DIR a panic injected in the simulation (a server
//                                     started with --test-panic) shows on the page
//                                     with its reason, and Reset runs the scene again
//   node view.mjs fps URL             frames per second the page draws, and bytes per
//                                     frame received, while the simulation runs
// Prints one JSON line of figures; exits non-zero (with the reason) on a failed check.
import { chromium } from 'playwright-core';

const [mode, url, out] = process.argv.slice(2);
const executablePath = process.env.CLEAVE_CHROMIUM || '/usr/bin/chromium';
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
const status = async () => (await fetch(new URL('/status', url))).json();

function check(ok, message) {
  if (!ok) throw new Error(message);
}

async function waitFor(what, predicate, ms) {
  const start = Date.now();
  for (;;) {
    const value = await predicate();
    if (value) return Date.now() - start;
    if (Date.now() - start > ms) throw new Error(`${what}: not within ${ms} ms`);
    await sleep(50);
  }
}

async function open(browser, errors) {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(url);
  await page.waitForFunction(() => window.cleave && window.cleave.drawn > 5 && window.cleave.positionsFrame >= 0);
  return page;
}

// pixels of a piece's colour (saturated; the ground, sky and colliders are grey) in
// the next frame the page draws
async function bodyPixels(page) {
  return page.evaluate(() => window.cleave.countBodyPixels());
}

async function drag(page, from, to, steps, button = 'left') {
  await page.mouse.move(from[0], from[1]);
  await page.mouse.down({ button });
  for (let i = 1; i <= steps; i++) {
    const t = i / steps;
    await page.mouse.move(from[0] + t * (to[0] - from[0]), from[1] + t * (to[1] - from[1]));
    await sleep(16);
  }
}

const distance = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);

async function checks(browser) {
  const errors = [];
  const figures = {};
  const page = await open(browser, errors);
  // the first frame shows the body
  await sleep(500);
  const pixels = await bodyPixels(page);
  figures.body_pixels = pixels;
  check(pixels > 0.05 * 800 * 600, `the body covers ${pixels} pixels of the first frames`);
  await page.screenshot({ path: `${out}/view.png` });
  check((await status()).pieces === 1, 'one piece before the stroke');

  // a stroke from above the block to below it, right of its middle
  await drag(page, [430, 120], [430, 480], 12);
  await page.mouse.up();
  figures.stroke_to_two_pieces_ms = await waitFor('two pieces or more after the stroke',
    async () => (await status()).pieces >= 2, 3000);
  await sleep(400);
  await page.screenshot({ path: `${out}/view_cut.png` });

  // a second page sees the same simulation
  const second = await open(browser, errors);
  const [a, b] = await Promise.all([page, second].map((p) => p.evaluate(() => window.cleave.status)));
  // (a stroke may leave a crumb as a third piece on a slow machine: the pages must agree)
  figures.pieces_after_stroke = a.pieces;
  check(b.scene === a.scene && a.pieces >= 2 && b.pieces === a.pieces && Math.abs(b.frame - a.frame) < 60,
    `the second page sees ${b.scene} frame ${b.frame} with ${b.pieces} pieces, the first ${a.scene} frame ${a.frame} with ${a.pieces}`);
  await second.close();

  // start again, and grab the block and lift it
  await page.click('#reset');
  await waitFor('one piece after reset', async () => (await status()).pieces === 1, 3000);
  await sleep(500);
  const before = (await status()).bodies[0].centroid;
  await page.selectOption('#tool', 'grab');
  await drag(page, [400, 300], [400, 40], 24);
  await sleep(1500);
  const lifted = (await status()).bodies[0].centroid;
  await page.mouse.up();
  figures.grab_moved_m = distance(before, lifted);
  check(figures.grab_moved_m >= 0.5, `a grab and drag moved the block ${figures.grab_moved_m} m`);

  // pause stops the frames
  await page.click('#play');
  await waitFor('paused', async () => !(await status()).playing, 2000);
  await sleep(300);
  const frame = await page.textContent('#frame');
  await sleep(1000);
  check(await page.textContent('#frame') === frame, 'the frame counter moved while paused');
  check((await status()).frame === Number(frame), 'the server went on while paused');

  // bad messages are refused and the simulation goes on
  await page.evaluate(async () => {
    const ws = new WebSocket(`ws://${location.host}/ws`);
    await new Promise((resolve) => { ws.onopen = resolve; });
    for (const m of ['garbage', '{"cmd":"explode"}', '{"cmd":"scene","name":"../../etc/passwd"}',
      '{"cmd":"stroke","eye":[0,0],"from":[1,0,0],"to":[0,1,0]}',
      '{"cmd":"stroke","eye":[0,1,5],"from":[0,0,-1],"to":[0,0,-1]}',
      '{"cmd":"grab","eye":[0,50,0],"dir":[0,1,0]}', '{"cmd":"drag","eye":[0,0,0],"dir":[0,0,0]}',
      'x'.repeat(100000), new Uint8Array([1, 2, 3])]) ws.send(m);
    // a flood, which the log sums up instead of echoing
    for (let i = 0; i < 500; i++) ws.send('garbage');
    await new Promise((resolve) => setTimeout(resolve, 300));
    ws.close();
  });
  await page.click('#play');
  const resumed = (await status()).frame;
  await waitFor('frames after the bad messages', async () => (await status()).frame > resumed + 10, 3000);
  check((await status()).scene === 'slice', 'the scene stayed');

  // the scene picker, with the scene's own blades: dice cuts itself in four
  await page.check('#scripted');
  await page.selectOption('#scene', 'dice');
  figures.dice_to_four_pieces_ms = await waitFor('dice in four pieces',
    async () => { const s = await status(); return s.scene === 'dice' && s.pieces === 4; }, 10000);

  check(errors.length === 0, `console errors: ${errors.join(' | ')}`);
  return figures;
}

async function stopped(browser) {
  const errors = [];
  const page = await open(browser, errors);
  await page.evaluate(async () => {
    const ws = new WebSocket(`ws://${location.host}/ws`);
    await new Promise((resolve) => { ws.onopen = resolve; });
    ws.send('{"cmd":"panic"}');
    await new Promise((resolve) => setTimeout(resolve, 200));
    ws.close();
  });
  const figures = {};
  figures.stopped_shown_ms = await waitFor('the stopped notice',
    () => page.isVisible('#stopped'), 3000);
  const notice = await page.textContent('#stopped');
  check(notice.includes('the test-only panic command'), `the notice says: ${notice}`);
  await page.screenshot({ path: `${out}/view_stopped.png` });
  const s = await status();
  check(s.stopped && !s.playing, `the status after the panic: ${JSON.stringify(s.stopped)}`);
  // commands other than a reset are refused; a reset starts the scene again
  await page.click('#play');
  await sleep(300);
  check((await status()).stopped, 'play does not run a stopped simulation');
  await page.click('#reset');
  await waitFor('the notice gone after a reset', async () => !(await page.isVisible('#stopped')), 3000);
  await page.click('#play');
  const frame = (await status()).frame;
  await waitFor('frames after the reset', async () => (await status()).frame > frame + 10, 5000);
  check(errors.length === 0, `console errors: ${errors.join(' | ')}`);
  return figures;
}

async function fps(browser) {
  const errors = [];
  const page = await open(browser, errors);
  await sleep(6000);
  const sample = () => page.evaluate(() => ({ drawn: window.cleave.drawn, frame: window.cleave.positionsFrame,
    bytes: window.cleave.bytes, messages: window.cleave.messages, resolution: window.cleave.resolution }));
  const [a, t0] = [await sample(), Date.now()];
  await sleep(5000);
  const [b, t1] = [await sample(), Date.now()];
  const seconds = (t1 - t0) / 1000;
  const frames = b.frame - a.frame;
  check(errors.length === 0, `console errors: ${errors.join(' | ')}`);
  return {
    page_fps: (b.drawn - a.drawn) / seconds,
    simulation_frames_per_second: frames / seconds,
    bytes_per_frame: frames > 0 ? (b.bytes - a.bytes) / frames : 0,
    resolution: b.resolution,
  };
}

const browser = await chromium.launch({ executablePath, args: ['--enable-unsafe-swiftshader'] });
try {
  const run = { fps, stopped, check: checks }[mode];
  const figures = await run(browser);
  console.log(JSON.stringify(figures));
} catch (e) {
  console.error(`browser check failed: ${e.message}`);
  process.exitCode = 1;
} finally {
  await browser.close();
}
