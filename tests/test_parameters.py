"""Parameters defined once (issue 25): every dataclass that declares its fields with
``parameter()`` refuses a value just outside each declared bound, with one line naming the
field, and accepts its defaults."""

from dataclasses import fields, replace

import pytest

from mpfem_fenicsx.material import ElastoPlastic
from mpfem_fenicsx.parameters import Range, parameter_range
from mpfem_fenicsx.workflows.compaction import CompactionCase
from mpfem_fenicsx.workflows.hertz import HertzCase
from mpfem_fenicsx.workflows.two_spheres import TwoSphereCase

DECLARED = (CompactionCase, ElastoPlastic, HertzCase, TwoSphereCase)


def _just_outside(allowed: Range) -> list:
    step = 1 if allowed.kind is int else 1e-9 * max(1.0, abs(allowed.low or 0), abs(allowed.high or 0))
    values = []
    if allowed.low is not None:
        values.append(allowed.low if allowed.open_low else allowed.low - step)
    if allowed.high is not None:
        values.append(allowed.high if allowed.open_high else allowed.high + step)
    if allowed.choices:
        values.append("not-a-choice")
    return values


@pytest.mark.parametrize("cls", DECLARED, ids=lambda c: c.__name__)
def test_every_declared_bound_is_enforced(cls):
    default = cls()
    declared = [f.name for f in fields(cls) if "range" in f.metadata]
    assert len(declared) >= 5, declared
    for name in declared:
        allowed = parameter_range(cls, name)
        for value in _just_outside(allowed):
            with pytest.raises(ValueError, match=rf"{name} = .*(out of range|not allowed)"):
                replace(default, **{name: value})
        if allowed.kind is float and allowed.low is not None:  # the bound itself, if closed, is allowed
            if not allowed.open_low and (allowed.high is None or allowed.low <= allowed.high):
                try:
                    replace(default, **{name: float(allowed.low)})
                except ValueError as err:  # a rule between fields may still refuse it, not the range
                    assert "out of range" not in str(err), err


def test_a_range_reads_in_words():
    r = Range("Coulomb friction coefficient mu (-)", float, 0, 2)
    assert r.allowed() == ">= 0 and <= 2" and r.problem(1.0) is None
    assert r.problem(3.0) == "is out of range: must be >= 0 and <= 2 [Coulomb friction coefficient mu (-)]"
    assert r.problem(float("nan")) == "must be a finite number"
    assert Range("x", str, choices=("a", "b")).problem("c") == "is not allowed: must be one of 'a', 'b'"
    assert Range("x", float, optional=True).problem(None) is None and Range("x", float).problem(None) == "is required"
