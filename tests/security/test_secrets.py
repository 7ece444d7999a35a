"""Secrets stay secret (issue 25 L4): no key or token in any repr, the agent refuses a key file others can read."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from groundstation.links.hub_auth import HubSide, new_token
from groundstation.links.runs import new_run
from groundstation.session.agent_session import SessionConfig
from protocol import SignatureVerifier, Signer
from protocol.signing import KEY_SIZE, format_key

ROOT = Path(__file__).resolve().parents[2]


def test_no_key_or_token_appears_in_a_repr() -> None:
    key = bytes(range(0xA0, 0xA0 + KEY_SIZE))
    token = new_token()
    shown = " ".join(repr(x) for x in (SignatureVerifier(key), Signer(key, 1), SessionConfig(key=key),
                                       new_run(1, "tcp://127.0.0.1:1", "tcp://agent:1", token), HubSide(token)))
    for secret in (key.hex(), key.hex().upper(), str(key), token):
        assert secret not in shown


def test_the_agent_refuses_a_key_file_others_can_read(tmp_path: Path) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(format_key(bytes(KEY_SIZE)))
    key_file.chmod(0o644)
    done = subprocess.run([sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--key-file",
                           str(key_file)], capture_output=True, text=True, timeout=60, cwd=ROOT)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1 and "readable by others" in lines[0], done.stderr
    assert "chmod 600" in lines[0]
