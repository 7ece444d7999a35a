"""Parameters: the table as SPEC.md lists it, get/set by index and name, refusals, f32 values (SPEC.md 13)."""

from __future__ import annotations

import math

from groundstation.check.agent import get_param, is_f32, param_table, reach, require_set, set_param, states
from groundstation.check.probe import Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult, Mode, ParamType
from protocol import messages as m
from protocol import parameters as spec_params

SECTION = "13 Parameters"
_TYPES = {int(t) for t in ParamType}
MAX_STATES_REFUSED = 22_501  # decisions O2: 50 x 50 x 9 + 1 states must be refused


@check("params.list", SECTION, """PARAM_LIST → the ACK, then one PARAM_VALUE per parameter in index order. F32
       values are stored as f32; PARAM_VALUE value is the stored f32 widened exactly to f64, for defaults too;
       min/max of F32 parameters likewise f32-rounded.""")
def listing(probe: Probe) -> str:
    ex = probe.accepted(m.ParamListRequest())
    first = probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s)
    expect(first is not None, "no PARAM_VALUE after the ACK")
    assert first is not None
    count = first[1].count
    probe.wait(lambda _: len(probe.messages(m.ParamValue, ex.ack_at)) >= count, ex.ack_at, probe.timeouts.reply_s)
    values = probe.messages(m.ParamValue, ex.ack_at)[:count]
    expect(len(values) == count, f"{len(values)} of {count} PARAM_VALUEs")
    expect([v.index for v in values] == list(range(count)), "PARAM_VALUEs not in index order 0..count-1")
    problems = []
    for v in values:
        if v.count != count:
            problems.append(f"{v.name}: count {v.count}")
        if v.param_type not in _TYPES:
            problems.append(f"{v.name}: type {v.param_type}")
        if not v.name or len(v.name.encode()) > spec_params.NAME_BYTES:
            problems.append(f"index {v.index}: name {v.name!r}")
        if not v.minimum <= v.value <= v.maximum:
            problems.append(f"{v.name}: {v.value} outside [{v.minimum}, {v.maximum}]")
        if v.param_type == ParamType.F32 and not all(is_f32(x) for x in (v.value, v.minimum, v.maximum)):
            problems.append(f"{v.name}: value/min/max {v.value!r}/{v.minimum!r}/{v.maximum!r} not f32 widened")
    expect(len({v.name for v in values}) == count, "two parameters share a name")
    expect(not problems, "; ".join(problems[:4]))
    return f"{count} parameters, in order, f32 values exact"


@check("params.table", SECTION, """Every parameter with index, name, type, unit, default, min, max [as the
       parameter table of SPEC.md section 13 lists it]; a real agent reports simulator-only parameters with
       min = max = 0.""")
def table(probe: Probe) -> str:
    values = param_table(probe)
    problems = []
    for d in spec_params.PARAMS:
        v = values.get(d.name)
        if v is None:
            problems.append(f"{d.name} missing")
            continue
        if v.index != d.index or v.param_type != d.param_type:
            problems.append(f"{d.name}: index {v.index} type {v.param_type}, SPEC says {d.index} {int(d.param_type)}")
        if (v.minimum, v.maximum) not in ((d.minimum, d.maximum), d.firmware_range()):
            problems.append(f"{d.name}: range [{v.minimum!r}, {v.maximum!r}], SPEC says [{d.minimum!r}, {d.maximum!r}]")
    expect(not problems, "; ".join(problems[:4]) + (f" (+{len(problems) - 4} more)" if len(problems) > 4 else ""))
    return f"{len(spec_params.PARAMS)} parameters as SPEC.md lists them"


@check("params.get", SECTION, """Index: -1 → by name; 0..count-1 → by index (name ignored); any other →
       BAD_VALUE. No PARAM_VALUE follows a NACK.""")
def get(probe: Probe) -> str:
    by_index = probe.accepted(m.ParamGet(index=2, name="target_depth_m"), "PARAM_GET index 2")
    found = probe.wait_message(m.ParamValue, by_index.ack_at, probe.timeouts.reply_s)
    expect(found is not None and found[1].index == 2, "PARAM_GET index 2 (with another name) did not answer index 2")
    named = get_param(probe, "link_timeout_s")
    expect(named.name == "link_timeout_s", f"PARAM_GET by name answered {named.name!r}")
    count = named.count
    for index, name in ((-2, ""), (count, ""), (-1, "no_such_parameter")):
        ex = probe.command(m.ParamGet(index=index, name=name))
        expect(ex.result == AckResult.BAD_VALUE,
               f"PARAM_GET index {index} {name!r}: {result_name(ex.result)}, wanted BAD_VALUE")
        probe.barrier()
        expect(not probe.messages(m.ParamValue, ex.sent_at), f"a PARAM_VALUE followed the NACK of index {index}")
    return "by index, by name; index -2, index = count and an unknown name: BAD_VALUE, no PARAM_VALUE"


@check("params.set", SECTION, """Accepted → ACK then one PARAM_VALUE with the value as stored. F32 values are
       stored as f32.""")
def set_value(probe: Probe) -> str:
    old = get_param(probe, "link_timeout_s")
    try:
        reply = require_set(probe, "link_timeout_s", 12.3)
        expect(reply.value == spec_params.f32(12.3), f"12.3 came back as {reply.value!r}, wanted the f32 "
               f"{spec_params.f32(12.3)!r}")
        ex = probe.command(m.ParamSet(index=old.index, value=11.0, name=""))
        expect(ex.result == AckResult.ACCEPTED, f"PARAM_SET by index: {result_name(ex.result)}")
        probe.barrier()
        replies = probe.messages(m.ParamValue, ex.sent_at)
        expect(len(replies) == 1 and replies[0].value == 11.0, f"PARAM_SET by index answered {replies}")
    finally:
        set_param(probe, "link_timeout_s", old.value)
    return "12.3 stored as its f32; set by index answered once"


@check("params.refused", SECTION, """A value that is not finite, outside [min, max], or not integral for an integer
       or bool type (bool: 0 or 1) is refused with BAD_VALUE, nothing changes, and no PARAM_VALUE follows a
       NACK.""")
def refused(probe: Probe) -> str:
    values = param_table(probe)
    link = values["link_timeout_s"]
    cases = [("link_timeout_s", math.nan), ("link_timeout_s", math.inf), ("link_timeout_s", link.maximum * 2 + 1),
             ("link_timeout_s", -1.0), ("surface_on_link_loss", 0.5), ("surface_on_link_loss", 2.0),
             ("max_episodes", 2.5), ("max_episodes", -1.0)]
    for name, value in cases:
        before = values[name].value
        ex, reply = set_param(probe, name, value)
        expect(ex.result == AckResult.BAD_VALUE, f"{name} = {value}: {result_name(ex.result)}, wanted BAD_VALUE")
        probe.barrier()
        expect(reply is None and not probe.messages(m.ParamValue, ex.sent_at),
               f"{name} = {value}: a PARAM_VALUE followed the NACK")
        now = get_param(probe, name).value
        expect(now == before, f"{name} = {value} was refused but the value changed from {before} to {now}")
    return f"{len(cases)} bad values refused, nothing changed"


@check("params.set_target", "5 Commands: CMD_SET_TARGET", """CMD_SET_TARGET is PARAM_SET of target_depth_m (same
       range, same refusal).""")
def set_target(probe: Probe) -> str:
    target = get_param(probe, "target_depth_m")
    ex = probe.command(m.SetTarget(target_depth_m=target.maximum + 1.0))
    expect(ex.result == AckResult.BAD_VALUE, f"CMD_SET_TARGET {target.maximum + 1.0}: {result_name(ex.result)}")
    if probe.current_mode() != Mode.LEARNING:
        ex = probe.command(m.SetTarget(target_depth_m=target.value))
        expect(ex.result == AckResult.ACCEPTED, f"CMD_SET_TARGET {target.value}: {result_name(ex.result)}")
    after = get_param(probe, "target_depth_m").value
    expect(after == target.value, f"target_depth_m changed from {target.value} to {after}")
    return "above the maximum: BAD_VALUE; the current value: ACCEPTED"


@check("params.refused_in_mode", SECTION, """Refused-in: learner parameters in LEARNING and RECOVERING;
       plant/mission-of-the-episode parameters in LEARNING; the rest never. Value checks come before mode checks
       (BAD_VALUE wins over NOT_ALLOWED_IN_MODE).""", motion=True)
def refused_in_mode(probe: Probe) -> str:
    values = param_table(probe)
    settable = [d for d in spec_params.PARAMS if values[d.name].minimum != values[d.name].maximum]
    in_learning: set[str] = set()
    problems: list[str] = []
    for _ in range(8):
        reach(probe, Mode.LEARNING)
        for d in settable:
            if d.name in in_learning:
                continue
            ex = probe.command(m.ParamSet(index=-1, value=values[d.name].value, name=d.name))
            mode = probe.mode_before(ex)
            if mode is None:
                continue
            wanted = AckResult.NOT_ALLOWED_IN_MODE if mode in d.refused_in else AckResult.ACCEPTED
            if ex.result != wanted:
                problems.append(f"{d.name} in {mode.name}: {result_name(ex.result)}, wanted {wanted.name}")
            if mode == Mode.LEARNING:
                in_learning.add(d.name)
        if len(in_learning) == len(settable):
            break
    bad = probe.command(m.ParamSet(index=-1, value=math.nan, name="gamma"))
    expect(bad.result == AckResult.BAD_VALUE,
           f"gamma = NaN in {probe.mode_before(bad)}: {result_name(bad.result)}, wanted BAD_VALUE (value first)")
    expect(not problems, "; ".join(problems[:4]))
    expect(len(in_learning) == len(settable),
           f"only {len(in_learning)} of {len(settable)} parameters met the agent in LEARNING")
    return f"{len(settable)} parameters set in LEARNING (and the modes met on the way) as the table says"


@check("params.ram_budget", SECTION, """The agent refuses (BAD_VALUE, reason names the bytes) a learner parameter
       change whose model would not fit its RAM budget. 22 501 states are refused.""", motion=True)
def ram_budget(probe: Probe) -> str:
    reach(probe, Mode.IDLE)
    names = ("z_cells", "zdot_cells", "act_bins")
    old = {n: get_param(probe, n).value for n in names}
    refusals = []
    try:
        for name, value in zip(names, (50.0, 50.0, 9.0), strict=True):
            ex, _ = set_param(probe, name, value)
            if ex.result == AckResult.BAD_VALUE:
                refusals.append(name)
            else:
                expect(ex.result == AckResult.ACCEPTED, f"{name} = {value}: {result_name(ex.result)}")
        count = states(probe)
    finally:
        for name in reversed(names):
            set_param(probe, name, old[name])
    expect(bool(refusals), "50 x 50 x 9 cells (22 501 states) were all accepted")
    expect(count < MAX_STATES_REFUSED, f"the agent holds {count} states after the refusals")
    return f"refused {', '.join(refusals)}; S stayed {count}"
