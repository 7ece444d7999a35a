"""Turns a frozen config dataclass into the plain named tuple numba kernels take, typed by annotation."""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from collections.abc import Callable
from typing import Any

import numba

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


def direct_entry(kernel: Any, *example_args: Any) -> Callable[..., Any]:
    """kernel compiled for the types of example_args, as a function that skips numba's per-call dispatch.

    Calling a numba dispatcher types every argument first: for a spec tuple of ~45 fields that costs
    ~5 us, more than most of our kernels take to run, and the on-board program calls several per
    control step. The compiled entry point only unboxes its arguments (~0.5 us for a spec). It does
    not check them: callers must pass exactly the example's types (same array dtypes and layouts,
    same spec tuple class, floats where the example has floats).
    """
    entry: Callable[..., Any] = kernel.compile(tuple(numba.typeof(arg) for arg in example_args))
    return entry
