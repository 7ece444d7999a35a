// One headless Chromium (software rendering, a throwaway profile) for the scripts that shoot the Rerun web viewer
// (screenshot_live_view.mjs, replay_opening.mjs). Needs NODE_PATH=<dir with playwright-core>.
import { createRequire } from "node:module";
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

const require = createRequire(join(process.env.NODE_PATH || process.cwd(), "noop.js"));
const { chromium } = require("playwright-core");

// Opens url in a fresh headless Chromium, runs shoot(page), and closes the browser whatever happens.
export async function withViewerPage(url, shoot) {
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
    await shoot(page);
  } finally {
    await context.close();
  }
}
