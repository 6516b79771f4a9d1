"""Parameters defined once: every dataclass that declares its fields with
``parameter()`` refuses a value just outside each declared bound, with one line naming the
field, and accepts its defaults."""

from dataclasses import fields, replace

import pytest

from mpfem_fenicsx.case import (
    BoundarySection,
    CompactionCase,
    ContactSection,
    LoadingSection,
    MeshSection,
    OutputSection,
    PackingSection,
    SolverSection,
)
from mpfem_fenicsx.cli.casefile import SCHEMA
from mpfem_fenicsx.loading.stress_paths import ServoSettings, StressPath
from mpfem_fenicsx.material import ElastoPlastic
from mpfem_fenicsx.parameters import Range, parameter_range
from mpfem_fenicsx.workflows.deviatoric_surface import DeviatoricSurfaceCase
from mpfem_fenicsx.workflows.force_rupture import ForceRuptureCase
from mpfem_fenicsx.workflows.foundation import SqueezeCase, UniaxialCase
from mpfem_fenicsx.workflows.hertz import HertzCase
from mpfem_fenicsx.workflows.stress_probes import StressProbeCase
from mpfem_fenicsx.workflows.two_spheres import TwoSphereCase
from mpfem_fenicsx.workflows.yield_surface import YieldSurfaceCase

SECTIONS = (
    PackingSection,
    MeshSection,
    ContactSection,
    BoundarySection,
    LoadingSection,
    SolverSection,
    OutputSection,
)
DECLARED = (
    *SECTIONS,
    ElastoPlastic,
    HertzCase,
    TwoSphereCase,
    UniaxialCase,
    SqueezeCase,
    ServoSettings,
    StressPath,
    StressProbeCase,
    DeviatoricSurfaceCase,
    ForceRuptureCase,
    YieldSurfaceCase,
)
#: a valid instance of the classes whose defaults alone are not one
VALID = {ForceRuptureCase: lambda: ForceRuptureCase(base=CompactionCase.build(gamma=1e-2))}


def just_outside(allowed: Range) -> list:
    """Values a check must refuse: just below / above the bounds, and a non-choice."""
    step = (
        1 if allowed.kind is int else 1e-9 * max(1.0, abs(allowed.low or 0), abs(allowed.high or 0))
    )
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
    default = VALID.get(cls, cls)()
    declared = [f.name for f in fields(cls) if "range" in f.metadata]
    assert len(declared) >= 3, declared
    for name in declared:
        allowed = parameter_range(cls, name)
        for value in just_outside(allowed):
            with pytest.raises(ValueError, match=rf"{name} = .*(out of range|not allowed)"):
                replace(default, **{name: value})
        # the bound itself, if closed, is allowed
        if allowed.kind is float and allowed.low is not None:
            if not allowed.open_low and (allowed.high is None or allowed.low <= allowed.high):
                try:
                    replace(default, **{name: float(allowed.low)})
                # a rule between fields may still refuse it, not the range
                except ValueError as err:
                    assert "out of range" not in str(err), err


def test_a_range_reads_in_words():
    r = Range("Coulomb friction coefficient mu (-)", float, 0, 2)
    assert r.allowed() == ">= 0 and <= 2" and r.problem(1.0) is None
    assert (
        r.problem(3.0)
        == "is out of range: must be >= 0 and <= 2 [Coulomb friction coefficient mu (-)]"
    )
    assert r.problem(float("nan")) == "must be a finite number"
    assert (
        Range("x", str, choices=("a", "b")).problem("c")
        == "is not allowed: must be one of 'a', 'b'"
    )
    assert (
        Range("x", float, optional=True).problem(None) is None
        and Range("x", float).problem(None) == "is required"
    )


def test_shared_parameters_are_declared_once():
    """The stress-probe cases' consolidation times and servo are the stress path's declarations, and
    every case-file [control] key is a StressPath field (same range, same default)."""
    for name in ("ramp", "hold", "rate", "band", "integral_time", "filter_time", "measure"):
        assert parameter_range(StressProbeCase, name) == parameter_range(StressPath, name), name
    control = [key for key in SCHEMA if key.section == "control"]
    assert len(control) >= 15
    for key in control:
        assert key.range == parameter_range(StressPath, key.name), key.name
    assert parameter_range(ForceRuptureCase, "p_probe") == parameter_range(
        StressProbeCase, "p_probe"
    )


def test_the_case_file_keys_are_the_sections_fields():
    """Every declared field of a case section is the case-file key of the same name, and a case
    built from flat field names puts each value into its section."""
    keys = {(key.section, key.name) for key in SCHEMA if key.section != "control"}
    declared = {
        (section, f.name)
        for section, cls in (
            ("packing", PackingSection),
            ("mesh", MeshSection),
            ("contact", ContactSection),
            ("boundary", BoundarySection),
            ("loading", LoadingSection),
            ("solver", SolverSection),
            ("output", OutputSection),
            ("material", ElastoPlastic),
        )
        for f in fields(cls)
        if "range" in f.metadata
    }
    assert keys == declared
    case = CompactionCase.build(
        particles=30, condition="GDF", increments=77, directory="x", gamma=0.01
    )
    assert (
        case.packing.particles,
        case.boundary.condition,
        case.solver.increments,
        case.output.directory,
        case.contact.gamma,
    ) == (30, "GDF", 77, "x", 0.01)
    assert case.updated(solver={"increments": 5 * 77}).solver == SolverSection(increments=385)
    with pytest.raises(TypeError, match="no section or field 'bc'"):
        CompactionCase.build(bc="GDF")
