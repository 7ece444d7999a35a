"""How soon a replay opens on data: `dive replay FILE --viewer web` shot in headless Chromium at set moments.

Needs Debian's chromium and the npm package playwright-core (see scripts/screenshot_live_view.py):
    .venv/bin/python scripts/replay_opening.py HOUR.mcap --at 5,10,20 --out /tmp/opening

Prints when dive printed the viewer's address and when each screenshot was taken, counted from dive's start; the
screenshots are to be looked at (what the viewer shows is pixels, not a figure dive can read back).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("--at", default="5,10,20", help="seconds after dive's start to shoot the page at")
    parser.add_argument("--out", type=Path, default=Path("/tmp/replay-opening"), help="the screenshots' prefix")
    parser.add_argument("--node-path", default="/tmp/pw/node_modules", help="folder holding playwright-core")
    parser.add_argument("--web-port", type=int, default=9290)
    args = parser.parse_args()
    start_ms = int(time.time() * 1000)
    started = time.monotonic()
    dive = subprocess.Popen([sys.executable, "-m", "groundstation.cli.app", "replay", str(args.recording),
                             "--viewer", "web", "--web-port", str(args.web_port)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert dive.stdout is not None
        url = ""
        for line in dive.stdout:
            if "http://" in line:
                url = line[line.index("http://"):].split()[0]
                break
        if not url:
            raise SystemExit("dive replay printed no viewer address")
        print(f"{time.monotonic() - started:.1f} s: dive printed the viewer's address {url}")
        subprocess.run(["node", str(ROOT / "scripts" / "replay_opening.mjs"), url, str(args.out), str(start_ms),
                        args.at], check=True, timeout=300, env={**os.environ, "NODE_PATH": args.node_path})
    finally:
        dive.terminate()
        dive.wait(30)


if __name__ == "__main__":
    main()
