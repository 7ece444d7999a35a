// Shoots the Rerun web viewer in headless Chromium (software rendering) at several moments after a start time.
// Usage: NODE_PATH=<dir with playwright-core> node scripts/replay_opening.mjs URL OUT_PREFIX START_MS S1,S2,...
// Writes OUT_PREFIX-<S>s.png for each S: seconds after START_MS (a Date.now() stamp of when `dive replay` started).
import { withViewerPage } from "./headless_chromium.mjs";

const [url, prefix, startMs, moments] = process.argv.slice(2);
await withViewerPage(url, async (page) => {
  for (const s of moments.split(",").map(Number)) {
    const wait = Number(startMs) + s * 1000 - Date.now();
    if (wait > 0) await page.waitForTimeout(wait);
    const path = `${prefix}-${s}s.png`;
    await page.screenshot({ path });
    console.log(`${((Date.now() - Number(startMs)) / 1000).toFixed(1)} s: saved ${path}`);
  }
});
