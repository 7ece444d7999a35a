// Opens the Rerun web viewer in headless Chromium (software rendering) and saves a screenshot.
// Usage: NODE_PATH=<dir with playwright-core> node scripts/screenshot_live_view.mjs URL OUT.png [WAIT_S]
import { withViewerPage } from "./headless_chromium.mjs";

const [url, out, waitS = "40"] = process.argv.slice(2);
await withViewerPage(url, async (page) => {
  await page.waitForTimeout(Number(waitS) * 1000);  // the wasm viewer needs ~30 s with software rendering
  await page.screenshot({ path: out });
  console.log(`saved ${out}`);
});
