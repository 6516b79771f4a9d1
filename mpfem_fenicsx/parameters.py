"""Parameters defined once: a dataclass field carries its default with its meaning, unit and
allowed range.

A field declared with :func:`parameter` holds a :class:`Range` in its metadata. The dataclass
checks itself with :func:`check_parameters` (one-line ``ValueError`` naming the field and what
is allowed), and the case-file schema (:mod:`mpfem_fenicsx.cli.casefile`), the demos' options
and ``mpfem run --help`` read the same :class:`Range` through :func:`parameter_range`: a range
is written in one place only.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields
from typing import Any

_KIND_WORDS = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}


@dataclass(frozen=True)
class Range:
    """The values a parameter may take: ``kind`` (int, float, bool or str), bounds (inclusive
    unless ``open_low`` / ``open_high``) or ``choices``; ``optional``: None is allowed too.
    ``doc`` is the meaning with its unit, e.g. "Coulomb friction coefficient mu (-)"."""

    doc: str
    kind: type
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    choices: tuple | None = None
    optional: bool = False

    def allowed(self) -> str:
        """What is allowed, in words: "one of 'a', 'b'", ">= 2 and <= 5000", "a number"."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.open_low else '>='} {self.low:g}")
        if self.high is not None:
            parts.append(f"{'<' if self.open_high else '<='} {self.high:g}")
        return " and ".join(parts) if parts else _KIND_WORDS[self.kind]

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused ("is out of range: must be ..."), or None if it is allowed.
        The type is the caller's concern (a case file's TOML value, a command-line string)."""
        if value is None:
            return None if self.optional else "is required"
        if self.kind is float and not math.isfinite(value):
            return "must be a finite number"
        if self.choices:
            return None if value in self.choices else f"is not allowed: must be {self.allowed()}"
        bad_low = self.low is not None and (
            value <= self.low if self.open_low else value < self.low
        )
        bad_high = self.high is not None and (
            value >= self.high if self.open_high else value > self.high
        )
        return (
            f"is out of range: must be {self.allowed()} [{self.doc}]"
            if bad_low or bad_high
            else None
        )


def parameter(
    default: Any,
    doc: str,
    *,
    kind: type | None = None,
    low: float | None = None,
    high: float | None = None,
    open_low: bool = False,
    open_high: bool = False,
    choices: tuple | None = None,
) -> Any:
    """A dataclass field with ``default`` and its :class:`Range` (``kind`` defaults to the
    default's type; a None default makes the parameter optional and needs ``kind``)."""
    if kind is None:
        if default is None:
            raise TypeError("parameter: an optional (None) default needs its kind")
        kind = type(default)
    allowed = Range(
        doc,
        kind,
        low,
        high,
        open_low,
        open_high,
        None if choices is None else tuple(choices),
        optional=default is None,
    )
    return field(default=default, metadata={"range": allowed})


def parameter_of(cls: type, name: str, default: Any = MISSING) -> Any:
    """A dataclass field declared like ``cls.name`` (same meaning, unit and range), with the
    same default or ``default``: one declaration for a parameter two cases share."""
    a = parameter_range(cls, name)
    return parameter(
        parameter_default(cls, name) if default is MISSING else default,
        a.doc,
        kind=a.kind,
        low=a.low,
        high=a.high,
        open_low=a.open_low,
        open_high=a.open_high,
        choices=a.choices,
    )


def parameter_range(cls: type, name: str) -> Range:
    """The :class:`Range` of the field ``name`` of the dataclass ``cls``."""
    for f in fields(cls):
        if f.name == name and "range" in f.metadata:
            return f.metadata["range"]
    raise KeyError(f"{cls.__name__} has no parameter {name!r}")


def parameter_default(cls: type, name: str) -> Any:
    """The default of the field ``name`` of the dataclass ``cls``."""
    for f in fields(cls):
        if f.name == name:
            return None if f.default is MISSING else f.default
    raise KeyError(f"{cls.__name__} has no field {name!r}")


def check_parameters(obj: Any, prefix: str = "") -> None:
    """Check every :func:`parameter` field of the dataclass instance ``obj`` against its range:
    ValueError "<prefix><name> = <value> is out of range: must be ... [meaning (unit)]"."""
    for f in fields(obj):
        allowed = f.metadata.get("range")
        if allowed is not None:
            value = getattr(obj, f.name)
            why = allowed.problem(value)
            if why is not None:
                raise ValueError(f"{prefix}{f.name} = {value!r} {why}")
