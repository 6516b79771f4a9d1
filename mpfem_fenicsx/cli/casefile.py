"""Case files: a TOML description of a compaction run, validated before any computation.

One table, :data:`SCHEMA`, says every key: its section, type, default, allowed range, unit and
meaning. It drives the validation (unknown section or key, wrong type, out-of-range value ->
:class:`CaseError` naming the field and what is allowed), the documentation (``mpfem run
--help``, ``mpfem init``) and the conversion into a :class:`CompactionCase`.

Example (every key optional; defaults = the flagship demo)::

    [packing]
    particles = 50            # seeded frictionless packing ...
    # file = "packing.txt"    # ... or a packing file (path relative to the case file)

    [boundary]
    condition = "CLP"

    [loading]
    path = "isotropic"
    target_density = 0.95

    [solver]
    kind = "explicit"
    increments = 6000
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..material import ElastoPlastic
from ..parameters import Range, parameter_default, parameter_range
from ..workflows.compaction import CompactionCase
from .options import add_range_option


class CaseError(ValueError):
    """Invalid case file: the message names the file, the field and what is allowed."""


@dataclass(frozen=True)
class Key:
    """A case-file key ``[section] name``: the values it allows (``range``, its meaning and unit
    in ``range.doc``), its default and the CompactionCase attribute it sets (``target``;
    ``material.<x>``: an ElastoPlastic field). A key with a target takes range and default from
    that field's :func:`~mpfem_fenicsx.parameters.parameter` declaration (:func:`case_key`)."""

    section: str
    name: str
    range: Range
    default: Any = None
    target: str | None = None

    @property
    def kind(self) -> type:
        return self.range.kind

    @property
    def doc(self) -> str:
        return self.range.doc

    @property
    def choices(self) -> tuple | None:
        return self.range.choices

    @property
    def field(self) -> str:
        return f"[{self.section}] {self.name}"

    def allowed(self) -> str:
        return self.range.allowed()

    def check(self, value: Any, where: str) -> Any:
        """``value`` if it has the key's type and range, else CaseError naming ``where`` and the key."""
        ok_type = (isinstance(value, bool) if self.kind is bool else
                   isinstance(value, int) and not isinstance(value, bool) if self.kind is int else
                   isinstance(value, (int, float)) and not isinstance(value, bool) if self.kind is float else
                   isinstance(value, str))
        if not ok_type:
            raise CaseError(f"{where}: {self.field} = {value!r} has the wrong type: expected {_KIND_WORDS[self.kind]}")
        if self.kind is float:
            value = float(value)
        why = self.range.problem(value)
        if why is not None:
            raise CaseError(f"{where}: {self.field} = {value!r} {why}")
        return value


_KIND_WORDS = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}


def case_key(section: str, name: str, target: str | None = None) -> Key:
    """The key setting CompactionCase.``target`` (default: ``name``; ``material.<x>``: an
    ElastoPlastic field): range and default from the field's declaration."""
    target = target or name
    owner, attribute = (ElastoPlastic, target[9:]) if target.startswith("material.") else (CompactionCase, target)
    return Key(section, name, parameter_range(owner, attribute), parameter_default(owner, attribute), target)


def own_key(section: str, name: str, kind: type, doc: str, low: float | None = None, high: float | None = None,
            *, open_low: bool = False, open_high: bool = False, choices: tuple | None = None,
            default: Any = None, target: str | None = None) -> Key:
    """A key that sets no CompactionCase field of its own (the [control] keys build the stress
    control, [output] directory the results folder): its range here; optional without ``default``."""
    return Key(section, name, Range(doc, kind, low, high, open_low, open_high, choices, optional=default is None),
               default, target)


def _material(name: str) -> Key:
    return case_key("material", name, f"material.{name}")


#: every key of a case file (section order = the order of the documentation)
SCHEMA: tuple[Key, ...] = (
    # particles: thesis table 2.1 (lead)
    *(_material(name) for name in ("E", "nu", "sigma_0", "hardening", "K", "n", "H", "density")),
    # packing (thesis §2.2)
    case_key("packing", "particles"),
    case_key("packing", "r_min"),
    case_key("packing", "r_max"),
    case_key("packing", "seed"),
    case_key("packing", "fraction", "packing_fraction"),
    own_key("packing", "file", str, "packing file instead of the generator: 'dx dy dz' then one 'x y z r' line per "
            "sphere (mm; path relative to the case file)", target="packing_file"),
    # meshing (SPEC §2)
    case_key("mesh", "resolution", "mesh"),
    case_key("mesh", "refinement"),
    case_key("mesh", "radius_factor"),
    # contact law (thesis §3.3)
    case_key("contact", "friction"),
    case_key("contact", "gamma"),
    case_key("contact", "delta_max"),
    case_key("contact", "asperity_yield"),
    case_key("contact", "penalty_factor"),
    # boundary conditions (thesis table 2.2)
    case_key("boundary", "condition", "bc"),
    case_key("boundary", "images"),
    case_key("boundary", "d_bc"),
    # loading path (thesis §2.2.3)
    case_key("loading", "path", "loading"),
    case_key("loading", "target_density"),
    case_key("loading", "duration"),
    case_key("loading", "profile"),
    # solver (SPEC §6)
    case_key("solver", "kind", "solver"),
    case_key("solver", "increments"),
    case_key("solver", "steps"),
    case_key("solver", "damping"),
    case_key("solver", "local_damping"),
    case_key("solver", "hold"),
    # stress-controlled paths (loading.mixed; beyond the thesis, issue 24): times in units of the
    # [loading] duration, the servo's rate in strain per duration
    own_key("control", "path", str, "stress-controlled path replacing the compaction (CLP or CLPS, explicit): "
            "pressure = isotropic pressure ramp to `pressure`, then held; triaxial = the same consolidation, then "
            "axial compression along z at constant lateral stress; cycle = the same consolidation, unload to "
            "`unload_to`, reload to `reload_to` (each ramp `ramp`, each hold `hold`); lode = the same consolidation, "
            "then the von Mises stress ramped to `q_max` along `lode_angle` at constant mean stress over "
            "`shear_time`", choices=("none", "pressure", "triaxial", "cycle", "lode"), default="none"),
    own_key("control", "pressure", float, "target (pressure) or confining (triaxial) pressure (MPa, compression "
            "> 0); required with a path", 0, 1000, open_low=True),
    own_key("control", "ramp", float, "time of the pressure ramp (x duration; default 1)", 0, 100, open_low=True),
    own_key("control", "hold", float, "hold at the pressure after the ramp (x duration; default 0.3)", 0, 100),
    own_key("control", "axial_strain", float, "triaxial: axial Hencky shortening (-; default 0.1)", 0, 0.5,
            open_low=True),
    own_key("control", "axial_time", float, "triaxial: time of the axial compression (x duration; default 1)", 0,
            100, open_low=True),
    own_key("control", "unload_to", float, "cycle: pressure of the unload (MPa; required, below `pressure`)", 0,
            1000),
    own_key("control", "reload_to", float, "cycle: pressure of the reload (MPa; default `pressure`; above "
            "`unload_to`)", 0, 1000, open_low=True),
    own_key("control", "q_max", float, "lode: von Mises stress at the end of the shear (MPa; required)", 0, 1000,
            open_low=True),
    own_key("control", "lode_angle", float, "lode: Lode angle of the shear (degrees; 0 = triaxial compression "
            "along x, 60 = triaxial extension along z; default 0)", -360, 360),
    own_key("control", "shear_time", float, "lode: time of the shear ramp (x duration; default 1)", 0, 100,
            open_low=True),
    own_key("control", "rate", float, "the servo's largest strain rate (strain per duration; default 0.1)", 0, 10,
            open_low=True),
    own_key("control", "band", float, "stress error at which the servo reaches its rate (MPa; default: a quarter "
            "of the pressure)", 0, open_low=True),
    own_key("control", "integral_time", float, "integral time of the PI servo (x duration; default 0.1; 0: "
            "proportional only, which lags behind a drifting stress)", 0),
    own_key("control", "filter_time", float, "low-pass filter of the measured stress (x duration; default 0.01)",
            0),
    own_key("control", "measure", str, "the servo's stress: schmidt (auxiliary nodes' reactions, eq. 2.19; "
            "default) or volume (the particles' volume average, eq. C.7)", choices=("schmidt", "volume")),
    # outputs (SPEC §10)
    own_key("output", "directory", str, "results folder (default: results/<case file name>; --out overrides)",
            target="out_dir"),
    case_key("output", "outputs"),
    case_key("output", "visual"),
    case_key("output", "checkpoint_every"),
    case_key("output", "checkpoint_keep"),
)

SECTIONS = tuple(dict.fromkeys(k.section for k in SCHEMA))


def _keys(section: str) -> dict[str, Key]:
    return {k.name: k for k in SCHEMA if k.section == section}


def schema_key(section: str, name: str) -> Key:
    """The case-file key ``[section] name`` of :data:`SCHEMA`."""
    try:
        return _keys(section)[name]
    except KeyError:
        raise KeyError(f"no case-file key [{section}] {name}") from None


def add_schema_option(parser, section: str, name: str, flag: str | None = None, default: Any = "schema",
                      help: str | None = None) -> None:
    """A command-line option of the demos from the case-file key ``[section] name``: its type,
    default, choices and help (meaning, unit, allowed range) come from :data:`SCHEMA`, and the
    value is checked by the key's range like a case file's (:mod:`.options`: exit 2, one line
    naming the option). ``flag``: the option (default ``--name`` with dashes); ``default``:
    another default than the key's (e.g. a demo's own); ``help``: prepended to the key's meaning."""
    key = schema_key(section, name)
    add_range_option(parser, flag or "--" + name.replace("_", "-"), name, key.range,
                     key.default if default == "schema" else default, help)


def parse_case(data: dict, where: str = "case", base: Path | None = None) -> dict[str, Any]:
    """Validated values of a parsed TOML document: {(section, key): value} of the keys given."""
    values: dict[tuple[str, str], Any] = {}
    for section, table in data.items():
        if section not in SECTIONS:
            raise CaseError(f"{where}: unknown section [{section}] (allowed: {', '.join(SECTIONS)})")
        if not isinstance(table, dict):
            raise CaseError(f"{where}: {section} must be a [{section}] table, got {table!r}")
        keys = _keys(section)
        for name, value in table.items():
            if name not in keys:
                raise CaseError(f"{where}: unknown key [{section}] {name} (allowed: {', '.join(keys)})")
            values[(section, name)] = keys[name].check(value, where)
    # checks between keys
    get = lambda s, k: values.get((s, k), next(x.default for x in SCHEMA if (x.section, x.name) == (s, k)))
    if get("packing", "r_max") < get("packing", "r_min"):
        raise CaseError(f"{where}: [packing] r_max = {get('packing', 'r_max')!r} is out of range: must be >= "
                        f"r_min = {get('packing', 'r_min')!r} mm")
    if ("packing", "file") in values:
        given = [k for k in ("particles", "r_min", "r_max", "seed", "fraction") if ("packing", k) in values]
        if given:
            raise CaseError(f"{where}: [packing] file and [packing] {given[0]} exclude each other (the file "
                            "gives the spheres; the other keys drive the generator)")
        path = Path(values[("packing", "file")])
        if not path.is_absolute() and base is not None:
            path = base / path
        if not path.is_file():
            raise CaseError(f"{where}: [packing] file = {values[('packing', 'file')]!r}: no such file ({path})")
        values[("packing", "file")] = str(path)
    control = [k for (section, k) in values if section == "control" and k != "path"]
    if get("control", "path") == "none" and control:
        raise CaseError(f"{where}: [control] {control[0]} needs a [control] path (pressure or triaxial)")
    if get("control", "path") != "none" and ("control", "pressure") not in values:
        raise CaseError(f"{where}: [control] pressure is required with path = {get('control', 'path')!r} (MPa, > 0)")
    path_keys = {"triaxial": ("axial_strain", "axial_time"), "cycle": ("unload_to", "reload_to"),
                 "lode": ("q_max", "lode_angle", "shear_time")}
    for owner, keys in path_keys.items():
        stray = [k for k in keys if k in control and get("control", "path") != owner]
        if stray:
            raise CaseError(f"{where}: [control] {stray[0]} belongs to path = {owner!r}")
    required = {"cycle": "unload_to", "lode": "q_max"}.get(get("control", "path"))
    if required and ("control", required) not in values:
        raise CaseError(f"{where}: [control] {required} is required with path = {get('control', 'path')!r}")
    if get("control", "path") == "cycle":
        pressure, unload_to = get("control", "pressure"), get("control", "unload_to")
        reload_to = values.get(("control", "reload_to"), pressure)
        if not unload_to < pressure or not reload_to > unload_to:
            raise CaseError(f"{where}: [control] unload_to must be below pressure = {pressure} MPa and reload_to "
                            f"above it, got unload_to = {unload_to}, reload_to = {reload_to}")
    if get("boundary", "images") and get("boundary", "condition") != "CLP":
        raise CaseError(f"{where}: [boundary] images = true realizes CLP only, got condition = "
                        f"{get('boundary', 'condition')!r}")
    return values


def load_case(path: str | Path, out_dir: str | None = None) -> CompactionCase:
    """Read, validate and convert a case file (raises :class:`CaseError`)."""
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise CaseError(f"{where}: no such case file")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{where}: not valid TOML: {err}") from None
    values = parse_case(data, where, base=path.parent)
    return to_case(values, out_dir or values.get(("output", "directory")) or f"results/{path.stem}", where)


def to_case(values: dict[tuple[str, str], Any], out_dir: str, where: str = "case") -> CompactionCase:
    """A CompactionCase from validated values (defaults for the keys not given)."""
    material = {}
    kwargs: dict[str, Any] = {"out_dir": out_dir}
    for key in SCHEMA:
        if (key.section, key.name) not in values or key.target in ("out_dir", None):
            continue
        value = values[(key.section, key.name)]
        if key.target.startswith("material."):
            material[key.target[9:]] = value
        else:
            kwargs[key.target] = value
    try:
        if material:
            kwargs["material"] = ElastoPlastic(**material)
        control = {k: v for (section, k), v in values.items() if section == "control"}
        if control.get("path", "none") != "none":
            kwargs["control"] = stress_control(control, kwargs.get("duration", parameter_default(CompactionCase, "duration")))
        return CompactionCase(**kwargs)
    except ValueError as err:  # a rule of the case classes not expressed in the schema
        raise CaseError(f"{where}: {err}") from None


def stress_control(keys: dict[str, Any], duration: float):
    """The StressControl of the [control] keys (times x ``duration`` s, rate / duration)."""
    from ..loading.mixed import lode_direction, normal_stress_path, pressure_control, triaxial_control

    pressure = keys["pressure"]
    integral = keys.get("integral_time", 0.1)
    servo = dict(rate=keys.get("rate", 0.1) / duration, band=keys.get("band", pressure / 4),
                 measure=keys.get("measure", "schmidt"), filter_time=keys.get("filter_time", 0.01) * duration,
                 integral_time=integral * duration if integral > 0 else None)
    ramp, hold = keys.get("ramp", 1.0) * duration, keys.get("hold", 0.3) * duration
    if keys["path"] == "pressure":
        return pressure_control(pressure, ramp, hold, **servo)
    if keys["path"] in ("cycle", "lode"):
        p = np.full(3, pressure)
        if keys["path"] == "cycle":  # load, hold, unload, hold, reload, hold
            low, high = np.full(3, keys["unload_to"]), np.full(3, keys.get("reload_to", pressure))
            stages = [(ramp, p), (hold, p), (ramp, low), (hold, low), (ramp, high), (hold, high)]
        else:  # load, hold, then q ramped at constant mean stress along the Lode angle
            theta = np.radians(keys.get("lode_angle", 0.0))
            sheared = p + np.sqrt(2.0 / 3.0) * keys["q_max"] * lode_direction(theta)
            stages = [(ramp, p), (hold, p), (keys.get("shear_time", 1.0) * duration, sheared)]
        times, stresses = [0.0], [np.zeros(3)]
        for length, stress in stages:
            if length > 0:
                times.append(times[-1] + length)
                stresses.append(stress)
        return normal_stress_path(times, stresses, **servo)
    return triaxial_control(pressure, consolidation=ramp, hold=hold, axial_strain=keys.get("axial_strain", 0.1),
                            axial_time=keys.get("axial_time", 1.0) * duration, **servo)


def documentation() -> str:
    """The case-file reference: every section and key with type, default, range, meaning."""
    lines = []
    for section in SECTIONS:
        lines.append(f"[{section}]")
        for k in SCHEMA:
            if k.section == section:
                default = "(none)" if k.default is None else repr(k.default)
                lines.append(f"  {k.name:<17} {k.kind.__name__:<5} default {default:<10} {k.allowed()}: {k.doc}")
    return "\n".join(lines)


def example_case() -> str:
    """A complete, commented case file with every default (``mpfem init``)."""
    out = ["# mpfem case file: compaction of a periodic volume of elastoplastic particles.",
           "# Every key is optional; the values below are the defaults (the flagship demo).",
           "# Units: mm, N, MPa, s, t/mm^3. Reference: `mpfem run --help`.", ""]
    for section in SECTIONS:
        out.append(f"[{section}]")
        for k in SCHEMA:
            if k.section != section:
                continue
            if k.default is None:
                out.append(f"{'# ' + k.name + ' = ...':<30} # {k.doc}; {k.allowed()}")
            else:
                value = ("true" if k.default else "false") if k.kind is bool else (
                    f'"{k.default}"' if k.kind is str else repr(k.default))
                out.append(f"{k.name + ' = ' + value:<30} # {k.doc}; {k.allowed()}")
        out.append("")
    return "\n".join(out)
