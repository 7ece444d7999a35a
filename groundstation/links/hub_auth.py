"""The hub's handshake: a tool and a `dive run` prove to each other that they hold the run's token, before any frame.

Why a token over loopback TCP (and not a Unix socket with a peer-credential check): it works the same on Linux and
macOS (peer credentials are SO_PEERCRED on one, LOCAL_PEERCRED / getpeereid on the other), keeps the one TCP link
code for agents and hubs, and proves the run too, not only the tool. The token is 32 random bytes in the run's
announcement file, mode 0600 in a 0700 folder: only the run's owner (and root) can read it. Neither side ever sends
it: each sends an HMAC-SHA256 of both sides' fresh nonces under it. So a process that took a dead run's PID and
port (issue 25 H2) can neither pass for the run (it cannot answer) nor learn anything to replay, and bytes from
anyone else (issue 25 H3) end at the first line, before a frame is decoded.

    tool -> hub:  DIVE-HUB/1 <tool nonce, 32 hex>\\n
    hub  -> tool: <hub nonce, 32 hex> <HMAC(token, "hub|" tool nonce "|" hub nonce), hex>\\n
    tool -> hub:  <HMAC(token, "tool|" tool nonce "|" hub nonce), hex>\\n      then the agent's frame protocol
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import socket
import time

from groundstation.errors import LinkError

GREETING = b"DIVE-HUB/1 "
FULL = b"DIVE-HUB/1 FULL\n"  # the hub's one line to a connection it has no slot for, before it closes it
TOKEN_BYTES = 32
NONCE_HEX = 32
LINE_LIMIT = 160  # the longest line either side sends is 97 bytes: more before a newline is not a handshake
HANDSHAKE_TIMEOUT_S = 3.0


class HubAuthError(LinkError):
    """The other side of a hub connection did not prove it holds the run's token."""


class HubProofError(HubAuthError):
    """It answered the handshake with a proof that is wrong: whatever listens there is not the run. Only this
    withdraws a run's announcement: a reset, a timeout or a full hub says nothing about whose port it is (N2)."""


class HubFullError(HubAuthError):
    """The run's hub has no slot free (its tools' connections): try again later."""


def new_token() -> str:
    return secrets.token_hex(TOKEN_BYTES)


def _proof(token: str, role: bytes, tool_nonce: bytes, hub_nonce: bytes) -> bytes:
    try:
        key = bytes.fromhex(token)
    except ValueError:
        key = b""  # an announcement without a valid token proves nothing: no proof will match
    return hmac.new(key, role + b"|" + tool_nonce + b"|" + hub_nonce, hashlib.sha256).hexdigest().encode()


def _nonce_ok(nonce: bytes) -> bool:
    return len(nonce) == NONCE_HEX and all(c in b"0123456789abcdef" for c in nonce)


class HubSide:
    """One connection's handshake on the hub: feed() what arrives; `done` once the tool proved the token."""

    def __init__(self, token: str) -> None:
        self._token = token
        self._buffer = b""
        self._tool_nonce: bytes | None = None
        self._hub_nonce = secrets.token_hex(NONCE_HEX // 2).encode()
        self.done = False

    def __repr__(self) -> str:
        return f"HubSide(done={self.done})"  # never the token

    @property
    def greeted(self) -> bool:
        """A valid first line came: a tool mid-handshake, not bytes that are none (the hub evicts those first)."""
        return self._tool_nonce is not None

    def feed(self, data: bytes) -> tuple[bytes, bytes]:
        """(what to send the tool, bytes after the handshake: frames); HubAuthError when it is no handshake."""
        self._buffer += data
        reply = b""
        while not self.done:
            line, newline, rest = self._buffer.partition(b"\n")
            if not newline:
                if len(self._buffer) > LINE_LIMIT:
                    raise HubAuthError("no hub handshake")
                return reply, b""
            self._buffer = rest
            if self._tool_nonce is None:
                nonce = line.removeprefix(GREETING)
                if not line.startswith(GREETING) or not _nonce_ok(nonce):
                    raise HubAuthError("no hub handshake")
                self._tool_nonce = nonce
                reply += self._hub_nonce + b" " + _proof(self._token, b"hub", nonce, self._hub_nonce) + b"\n"
            elif hmac.compare_digest(line, _proof(self._token, b"tool", self._tool_nonce, self._hub_nonce)):
                self.done = True
            else:
                raise HubAuthError("wrong token")
        rest, self._buffer = self._buffer, b""
        return reply, rest


def tool_side(sock: socket.socket, token: str, who: str, timeout_s: float = HANDSHAKE_TIMEOUT_S) -> None:
    """The tool's side on a connected socket (left blocking with its old timeout); HubAuthError in one line."""
    old_timeout = sock.gettimeout()
    deadline = time.monotonic() + timeout_s
    tool_nonce = secrets.token_hex(NONCE_HEX // 2).encode()
    try:
        sock.settimeout(timeout_s)
        sock.sendall(GREETING + tool_nonce + b"\n")
        line = b""
        while not line.endswith(b"\n"):
            sock.settimeout(max(0.01, deadline - time.monotonic()))
            chunk = sock.recv(LINE_LIMIT - len(line))
            if not chunk or len(line) + len(chunk) >= LINE_LIMIT:
                break
            line += chunk
        if line == FULL:
            raise HubFullError(f"{who} is full: every tool slot of the run is taken (close a `dive view` or "
                               "`dive status --watch`, then try again)")
        if not line.endswith(b"\n"):
            raise HubAuthError(f"{who} closed the hub handshake without an answer (a loaded machine? try again)")
        hub_nonce, _, proof = line.rstrip(b"\n").partition(b" ")
        if not _nonce_ok(hub_nonce) or not hmac.compare_digest(proof, _proof(token, b"hub", tool_nonce, hub_nonce)):
            raise HubProofError(f"{who} did not prove it holds the run's token: it is not that run (the run has "
                                "ended and another program has its port?)")
        sock.sendall(_proof(token, b"tool", tool_nonce, hub_nonce) + b"\n")
    except HubAuthError:
        raise  # a LinkError is an OSError: not to be wrapped again below
    except TimeoutError as e:
        raise HubAuthError(f"{who} did not answer the hub handshake within {timeout_s:g} s") from e
    except OSError as e:
        raise HubAuthError(f"{who}: hub handshake failed ({e.strerror or e})") from e
    finally:
        sock.settimeout(old_timeout)
