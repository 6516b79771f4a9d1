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

from ..loading.stress_paths import PATH_FIELDS, StressPath
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


def control_key(name: str) -> Key:
    """The ``[control]`` key ``name``: a :class:`~mpfem_fenicsx.loading.stress_paths.StressPath`
    field (range and default from its declaration); the keys together build the path."""
    return Key("control", name, parameter_range(StressPath, name), parameter_default(StressPath, name))


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
    case_key("solver", "constraint_mass"),
    case_key("solver", "hold"),
    # stress-controlled paths (loading.mixed; beyond the thesis, issue 24): times in units of the
    # [loading] duration, the servo's rate in strain per duration
    *(control_key(name) for name in ("path", "pressure", "ramp", "hold", "axial_strain", "axial_time", "axial_ramp",
                                      "unload_to", "reload_to", "q_max", "lode_angle", "shear_time", "rate", "band",
                                      "band_fraction", "integral_time", "filter_time", "measure")),
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
    for owner, keys in PATH_FIELDS.items():
        stray = [k for k in keys if k in control and get("control", "path") != owner]
        if stray:
            raise CaseError(f"{where}: [control] {stray[0]} belongs to path = {owner!r}")
    stress_path(values, where)  # the rules between the path's keys
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
        path = stress_path(values, where)
        if path.path != "none":
            kwargs["control"] = path.control(kwargs.get("duration", parameter_default(CompactionCase, "duration")))
        return CompactionCase(**kwargs)
    except ValueError as err:  # a rule of the case classes not expressed in the schema
        raise CaseError(f"{where}: {err}") from None


def stress_path(values: dict[tuple[str, str], Any], where: str = "case") -> StressPath:
    """The :class:`StressPath` of the validated ``[control]`` keys (CaseError naming the key that
    breaks a rule between them)."""
    try:
        return StressPath(**{k: v for (section, k), v in values.items() if section == "control"})
    except ValueError as err:
        raise CaseError(f"{where}: [control] {err}") from None


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
                # a [control] key needs a path: shown with its default, commented out
                comment = "# " if k.section == "control" and k.name != "path" else ""
                out.append(f"{comment + k.name + ' = ' + value:<30} # {k.doc}; {k.allowed()}")
        out.append("")
    return "\n".join(out)
