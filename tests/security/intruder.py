"""Another local user's attack on a run (run as that user by test_another_user.py): the system Python and protocol/.

argv: the runs folder, the hub's port (found in /proc/net/tcp or by ss, as any user can). Prints one JSON line.
"""

from __future__ import annotations

import json
import socket
import sys
import time
from pathlib import Path

from protocol import FrameEncoder, StreamDecoder
from protocol import messages as m


def main() -> None:
    folder, port = Path(sys.argv[1]), int(sys.argv[2])
    report: dict[str, object] = {"read": [], "frames": 0}
    try:
        for path in folder.glob("*.json"):
            report["read"].append(path.read_text())  # type: ignore[attr-defined]
    except OSError as e:
        report["folder"] = type(e).__name__
    encoder, decoder = FrameEncoder(), StreamDecoder()
    hello = m.Hello(protocol_version=1, node_kind=2, definitions_hash=0, firmware_major=0, firmware_minor=0,
                    firmware_patch=0, node_id=7, boot_id=7, name="intruder")
    with socket.create_connection(("127.0.0.1", port), timeout=1.0) as sock:
        try:
            sock.sendall(b"".join(encoder.encode(msg).wire for msg in (
                hello, m.Text(t_us=0, severity=1, text="intruder was here"),
                m.ParamSet(index=-1, value=0.42, name="z_tol_m"), m.Surface())))
            deadline = time.monotonic() + 1.5
            while time.monotonic() < deadline:
                data = sock.recv(65536)
                if not data:
                    break
                report["frames"] = int(report["frames"]) + len(decoder.feed(data))  # type: ignore[call-overload]
        except OSError:
            pass
    print(json.dumps(report))


if __name__ == "__main__":
    main()
