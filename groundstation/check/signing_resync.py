"""Signing rules 1.2 added and 1.3's review found untested: the 10 s cap on the estimate and the signed re-sync.

An agent that lacks either passed `dive check` 1.2 (spec review of 1.2); each check here fails it
(tests/groundstation/broken_agent.py: `no-estimate-cap`, `no-resync`).
"""

from __future__ import annotations

import time

from groundstation.check.probe import Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult, Signer
from protocol import messages as m
from protocol.signing import RESYNC_NAME, resync_nonce

SECTION = "12 Signing: checking, re-sync (1.3)"
AHEAD_S = 30.0  # a new link id this far ahead is accepted (within 60 s) and moves the estimate up by only 10 s
BEHIND_S = 40.0  # then a new link id this far behind is 50 s behind a capped estimate (accepted), 70 s uncapped


def _get() -> m.ParamGet:
    return m.ParamGet(index=0, name="")


def _signer(probe: Probe, offset_s: float, step: int) -> Signer:
    """The probe's key on a link id of its own (`step` past the probe's), its clock `offset_s` from now."""
    assert probe.key is not None
    own = probe.signer.link_id if probe.signer else 0
    return Signer(probe.key, (own + step) % 256, clock_ns=lambda: time.time_ns() + int(offset_s * 1e9))


@check("signing.estimate_cap", SECTION, """if the timestamp is higher than the current estimate (step 4), the
       estimate moves up to it, but by at most 10 s in one frame, so a clock ahead cannot carry the estimate a
       minute per frame until every new link_id is refused as too old""", key=True)
def estimate_cap(probe: Probe) -> str:
    ahead = probe.command(_get(), signer=_signer(probe, AHEAD_S, 101))
    expect(ahead.ack is not None and ahead.ack.result == AckResult.ACCEPTED,
           f"a new link id {AHEAD_S:g} s ahead: {result_name(ahead.ack.result) if ahead.ack else 'no ACK'}, "
           "wanted ACCEPTED (within the 60 s too-new bound)")
    behind = probe.command(_get(), signer=_signer(probe, -BEHIND_S, 102))
    expect(behind.ack is not None and behind.ack.result == AckResult.ACCEPTED,
           f"then a new link id {BEHIND_S:g} s behind: "
           f"{result_name(behind.ack.result) if behind.ack else 'no ACK'} ({behind.ack.reason if behind.ack else ''}), "
           f"wanted ACCEPTED: one frame {AHEAD_S:g} s ahead may move the estimate by 10 s only")
    return f"{AHEAD_S:g} s ahead accepted, then a new link id {BEHIND_S:g} s behind accepted (the estimate capped)"


@check("signing.resync", SECTION, """Every UNAUTHORIZED it answers for a timestamp [...] ends its reason with
       re-sync nonce followed by the nonce as 8 lower-case hex digits [...] The re-sync is a PARAM_SET with index −1,
       name resync and value = the nonce [...] validly signed [...] A value other than the current nonce → refuse
       (stale re-sync nonce, UNAUTHORIZED, counted, not remembered in the ACK memory [...] Otherwise accept [...] the
       agent answers ACCEPTED with a non-empty reason saying it re-synced. No PARAM_VALUE follows""", key=True)
def resync(probe: Probe) -> str:
    old = probe.command(_get(), signer=_signer(probe, -70.0, 103))  # a new link id over 60 s behind: too old
    expect(old.ack is not None and old.ack.result == AckResult.UNAUTHORIZED,
           f"a new link id 70 s behind: {result_name(old.ack.result) if old.ack else 'no ACK'}, wanted UNAUTHORIZED")
    assert old.ack is not None
    nonce = resync_nonce(old.ack.reason)
    expect(nonce is not None, f"the refusal names no re-sync nonce: {old.ack.reason!r}")
    assert nonce is not None
    before = probe.counters().signing_rejects
    wrong = probe.command(m.ParamSet(index=-1, value=float(nonce ^ 0x5A5A5A5A), name=RESYNC_NAME))
    expect(wrong.ack is not None and wrong.ack.result == AckResult.UNAUTHORIZED,
           f"a re-sync with a wrong nonce: {result_name(wrong.ack.result) if wrong.ack else 'no ACK'}, "
           "wanted UNAUTHORIZED")
    counted = (probe.counters().signing_rejects - before) & 0xFFFFFFFF
    expect(counted == 1, f"a re-sync with a wrong nonce: signing_rejects +{counted}, wanted +1")
    done = probe.command(m.ParamSet(index=-1, value=float(nonce), name=RESYNC_NAME))
    expect(done.ack is not None and done.ack.result == AckResult.ACCEPTED,
           f"the re-sync with nonce {nonce:08x}: {result_name(done.ack.result) if done.ack else 'no ACK'} "
           f"({done.ack.reason if done.ack else ''}), wanted ACCEPTED")
    assert done.ack is not None
    expect(bool(done.ack.reason), "the re-sync's ACK has no reason saying it re-synced")
    probe.barrier()
    expect(not probe.messages(m.ParamValue, done.sent_at), "a PARAM_VALUE followed the re-sync")
    return f"nonce {nonce:08x}: a wrong one refused and counted, the right one ACCEPTED ({done.ack.reason})"
