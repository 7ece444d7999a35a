"""The parameter half of `python -m protocol.gen_c`: proto_params.h/.c from protocol/parameters.py."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

from protocol.enums import Mode, ParamType


def _mode_mask(modes: tuple[Mode, ...]) -> int:
    mask = 0
    for mode in modes:
        mask |= 1 << int(mode)
    return mask


def files(params: ModuleType, f32_literal: Callable[[float], str], banner: str) -> dict[str, str]:
    """proto_params.h and proto_params.c: the table in index order, with the firmware's ranges."""
    defs = params.PARAMS
    name_bytes = int(params.NAME_BYTES)
    header = [
        banner, "#ifndef PROTO_PARAMS_H", "#define PROTO_PARAMS_H", "", "#include <stdint.h>", "",
        f"#define PARAM_COUNT {len(defs)}u",
        f"#define PARAM_NAME_BYTES {name_bytes}u",
        f"#define PARAM_RAM_BUDGET_BYTES {int(params.RAM_BUDGET_BYTES)}u  /* learner model + snapshot copies */",
        f"#define PARAM_SNAPSHOTS_HELD {int(params.SNAPSHOTS_HELD)}u",
        f"#define PARAM_SNAPSHOT_BYTES_PER_STATE {int(params.SNAPSHOT_BYTES_PER_STATE)}u",
        f"#define PARAM_SHARED_SNAPSHOT_BYTES_PER_STATE {int(params.SHARED_SNAPSHOT_BYTES_PER_STATE)}u"
        "  /* Q_VALUES rendered live */",
        "",
        "typedef enum {",
        *[f"    PARAM_{d.name.upper()} = {d.index}," for d in defs],
        "} param_index_t;",
        "",
        "typedef struct {",
        f"    char name[{name_bytes}];  /* UTF-8, NUL-padded */",
        "    uint8_t param_type;       /* ParamType */",
        "    uint8_t learner;          /* a change restarts the learner and is checked against the RAM budget */",
        "    uint8_t refused_in_modes; /* bit m set: PARAM_SET refused with NOT_ALLOWED_IN_MODE in Mode m */",
        "    float default_value;      /* the real agent's default, as stored (f32) */",
        "    float minimum;            /* the range a real agent reports and enforces */",
        "    float maximum;",
        "} param_def_t;",
        "",
        "extern const param_def_t param_defs[PARAM_COUNT];",
        "",
        "#endif",
        "",
    ]
    rows = []
    for d in defs:
        low, high = d.firmware_range() if hasattr(d, "firmware_range") else (d.minimum, d.maximum)
        rows.append(
            f'    {{"{d.name}", {int(d.param_type)}u, {int(bool(d.learner))}u, 0x{_mode_mask(d.refused_in):02X}u, '
            f"{f32_literal(d.default)}, {f32_literal(low)}, {f32_literal(high)}}},  /* {d.index} "
            f"{ParamType(d.param_type).name} {d.unit} */"
        )
    source = [banner, '#include "proto_params.h"', "", "const param_def_t param_defs[PARAM_COUNT] = {", *rows, "};", ""]
    return {"proto_params.h": "\n".join(header), "proto_params.c": "\n".join(source)}
