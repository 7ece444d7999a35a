"""Turns a frozen config dataclass into the plain named tuple numba kernels take, typed by annotation."""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from typing import Any

# What kernels take: a namedtuple built from a config dataclass (field access is checked by the
# dataclass it mirrors, not by mypy, which cannot see dynamically built namedtuple fields).
KernelSpec = Any

_CASTS = {"float": float, "int": int, "bool": bool}


def kernel_tuple_type(config_cls: type, name: str) -> type:
    """A namedtuple class with the dataclass's fields, for numba (which cannot take dataclasses)."""
    cls = namedtuple(name, [f.name for f in dataclasses.fields(config_cls)])  # type: ignore[misc]
    cls.__module__ = config_cls.__module__
    return cls


def to_kernel_tuple(config: Any, tuple_cls: type) -> Any:
    """The config's values cast to their annotated scalar type, so an int 1 never recompiles a float slot."""
    values = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        annotation = field.type if isinstance(field.type, str) else field.type.__name__
        cast = _CASTS.get(annotation.split(".")[-1], None)
        values.append(cast(value) if cast is not None else int(value))
    return tuple_cls(*values)
