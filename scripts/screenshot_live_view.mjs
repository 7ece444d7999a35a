// Opens the Rerun web viewer in headless Chromium (software rendering) and saves a screenshot.
// Usage: NODE_PATH=<dir with playwright-core> node scripts/screenshot_live_view.mjs URL OUT.png [WAIT_S]
import { createRequire } from "node:module";
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

const require = createRequire(join(process.env.NODE_PATH || process.cwd(), "noop.js"));
const { chromium } = require("playwright-core");
const [url, out, waitS = "40"] = process.argv.slice(2);
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
  await page.waitForTimeout(Number(waitS) * 1000);  // the wasm viewer needs ~30 s with software rendering
  await page.screenshot({ path: out });
  console.log(`saved ${out}`);
} finally {
  await context.close();
}
