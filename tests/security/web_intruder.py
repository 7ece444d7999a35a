"""Another local user's attempt on a run's Rerun web viewer (run as that user by test_web_viewer_owner.py): the system
Python only. It asks the page port for the page and the data port for the recording as the browser's viewer does
(gRPC-web over HTTP/1.1, and gRPC over HTTP/2 as the SDK and the native viewer speak it), and tries the run's own
unix socket.

argv: the page port, the data port, the bridge's socket path. Prints one JSON line: per request the status line
and the bytes that came after the response's head; the socket's error.
"""

from __future__ import annotations

import json
import socket
import sys

HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes.fromhex("000000040000000000")  # + an empty SETTINGS
READ_MESSAGES = "/rerun.sdk_comms.v1alpha1.MessageProxyService/ReadMessages"


def ask(port: int, request: bytes) -> dict[str, object]:
    """Send `request`, read until the server closes (or 3 s pass): the status line and the bytes after the head."""
    got = b""
    error = ""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=3.0) as s:
            s.sendall(request)
            while chunk := s.recv(65536):
                got += chunk
    except OSError as e:  # a reset, or the time up while data kept coming
        error = type(e).__name__
    head, _, body = got.partition(b"\r\n\r\n")
    return {"status": head.split(b"\r\n", 1)[0].decode(errors="replace"), "bytes": len(got), "body": len(body),
            "error": error}


def main() -> None:
    web_port, grpc_port, bridge = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    grpc_web = (f"POST {READ_MESSAGES} HTTP/1.1\r\nHost: 127.0.0.1:{grpc_port}\r\n"
                "Content-Type: application/grpc-web+proto\r\nX-Grpc-Web: 1\r\nContent-Length: 5\r\n\r\n").encode()
    report: dict[str, object] = {
        "page": ask(web_port, f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{web_port}\r\nConnection: close\r\n\r\n".encode()),
        "grpc_web": ask(grpc_port, grpc_web + b"\0\0\0\0\0"),
        "grpc_h2": ask(grpc_port, HTTP2_PREFACE),
    }
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(3.0)
            s.connect(bridge)
            s.sendall(b"g")
            report["bridge"] = f"answered {s.recv(16)!r}"
    except OSError as e:
        report["bridge"] = type(e).__name__
    print(json.dumps(report))


if __name__ == "__main__":
    main()
