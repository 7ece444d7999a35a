// Shoots the Rerun web viewer in headless Chromium (software rendering) at several moments after a start time.
// Usage: NODE_PATH=<dir with playwright-core> node scripts/replay_opening.mjs URL OUT_PREFIX START_MS S1,S2,...
// Writes OUT_PREFIX-<S>s.png for each S: seconds after START_MS (a Date.now() stamp of when `dive replay` started).
import { createRequire } from "node:module";
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

const require = createRequire(join(process.env.NODE_PATH || process.cwd(), "noop.js"));
const { chromium } = require("playwright-core");
const [url, prefix, startMs, moments] = process.argv.slice(2);
const userDataDir = mkdtempSync(join(tmpdir(), "chromium-"));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: "/usr/bin/chromium",
  headless: true,
  viewport: { width: 1600, height: 1000 },
  args: ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"],
});
try {
  const page = context.pages()[0] ?? (await context.newPage());
  await page.goto(url, { timeout: 60000 });
  for (const s of moments.split(",").map(Number)) {
    const wait = Number(startMs) + s * 1000 - Date.now();
    if (wait > 0) await page.waitForTimeout(wait);
    const path = `${prefix}-${s}s.png`;
    await page.screenshot({ path });
    console.log(`${((Date.now() - Number(startMs)) / 1000).toFixed(1)} s: saved ${path}`);
  }
} finally {
  await context.close();
}
