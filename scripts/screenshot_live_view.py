"""Retake docs/live_view.png: the virtual agent learns while the web viewer is shot in headless Chromium.

Needs Debian's chromium (`apt-get install -y chromium`) and the npm package playwright-core:
    npm install --prefix /tmp/pw playwright-core
    .venv/bin/python scripts/screenshot_live_view.py --node-path /tmp/pw/node_modules
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from groundstation.links import make_link  # noqa: E402
from groundstation.session.agent_session import Session  # noqa: E402
from groundstation.view.rerun_sink import RerunView, ViewConfig, Viewer  # noqa: E402
from protocol import messages as m  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--node-path", default="/tmp/pw/node_modules", help="folder holding playwright-core")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "live_view.png")
    parser.add_argument("--url", default="sim://?speed=20&seed=3", help="the agent to watch while it learns")
    parser.add_argument("--wait", type=float, default=45.0, help="seconds the viewer gets to load and fill")
    parser.add_argument("--web-port", type=int, default=9190)
    parser.add_argument("--grpc-port", type=int, default=9976)
    args = parser.parse_args()
    config = ViewConfig(viewer=Viewer.WEB, web_port=args.web_port, grpc_port=args.grpc_port)
    with RerunView.open(config, name="live") as view:
        with Session(make_link(args.url), listeners=[view]) as session:
            session.set_param("dump_each_episode", 1)
            session.command(m.StartLearning(max_episodes=0))
            args.out.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run(["node", str(ROOT / "scripts" / "screenshot_live_view.mjs"), str(view.address),
                            str(args.out), str(args.wait)], check=True, timeout=args.wait + 120,
                           env={**os.environ, "NODE_PATH": args.node_path})
            session.command(m.Stop())


if __name__ == "__main__":
    main()
