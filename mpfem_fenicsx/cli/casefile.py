"""Case files: a TOML description of a compaction run, validated before any computation.

One table, :data:`SCHEMA`, says every key: its section, type, default, allowed range, unit and
meaning. It is derived from the declarations of the case's sections (:mod:`mpfem_fenicsx.case`:
a field declared with :func:`~mpfem_fenicsx.parameters.parameter` is the key ``[section] name``)
and of the stress paths (``[control]``, :class:`~mpfem_fenicsx.loading.stress_paths.StressPath`).
It drives the validation (unknown section or key, wrong type, out-of-range value ->
:class:`CaseError` naming the field and what is allowed), the documentation (``mpfem run
--help``, ``mpfem init``, the documentation's case-file reference) and the conversion into a
:class:`~mpfem_fenicsx.case.CompactionCase`.

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

import re
import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from ..case import SECTIONS, CompactionCase
from ..loading.stress_paths import PATH_FIELDS, StressPath
from ..parameters import Range, parameter_default


class CaseError(ValueError):
    """Invalid case file: the message names the file, the field and what is allowed."""


@dataclass(frozen=True)
class Key:
    """A case-file key ``[section] name``: the values it allows (``range``, its meaning and unit
    in ``range.doc``) and its default, both from the field's
    :func:`~mpfem_fenicsx.parameters.parameter` declaration (the case section's field
    ``section.name``, or a ``[control]`` StressPath field)."""

    section: str
    name: str
    range: Range
    default: Any = None

    @property
    def kind(self) -> type:
        """The key's value type: int, float, bool or str."""
        return self.range.kind

    @property
    def doc(self) -> str:
        """The key's meaning with its unit."""
        return self.range.doc

    @property
    def choices(self) -> tuple | None:
        """The values the key allows, or None if it takes a range."""
        return self.range.choices

    @property
    def field(self) -> str:
        """The key as written in messages: ``[section] name``."""
        return f"[{self.section}] {self.name}"

    def allowed(self) -> str:
        """What the key allows, in words."""
        return self.range.allowed()

    def check(self, value: Any, where: str) -> Any:
        """``value`` if it has the key's type and range, else CaseError naming ``where`` and the
        key."""
        ok_type = (
            isinstance(value, bool)
            if self.kind is bool
            else isinstance(value, int) and not isinstance(value, bool)
            if self.kind is int
            else isinstance(value, (int, float)) and not isinstance(value, bool)
            if self.kind is float
            else isinstance(value, str)
        )
        if not ok_type:
            raise CaseError(
                f"{where}: {self.field} = {value!r} has the wrong type: "
                f"expected {_KIND_WORDS[self.kind]}"
            )
        if self.kind is float:
            value = float(value)
        why = self.range.problem(value)
        if why is not None:
            raise CaseError(f"{where}: {self.field} = {value!r} {why}")
        return value


_KIND_WORDS = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}


def declared_keys(section: str, cls: type) -> list[Key]:
    """The keys of ``[section]``: the fields of ``cls`` declared with ``parameter()``, in order."""
    return [
        Key(section, f.name, f.metadata["range"], parameter_default(cls, f.name))
        for f in fields(cls)
        if "range" in f.metadata
    ]


#: every key of a case file, in the documentation's order: the case's sections (material: thesis
#: table 2.1, lead; packing §2.2; mesh; contact law §3.3; boundary conditions table 2.2; loading
#: path §2.2.3; solver; outputs), then the stress-controlled paths (``[control]``; times in units
#: of the [loading] duration, the servo's rate in strain per duration)
SCHEMA: tuple[Key, ...] = (
    *(key for name, cls in SECTIONS.items() for key in declared_keys(name, cls)),
    *declared_keys("control", StressPath),
)

#: the case file's sections, in order
FILE_SECTIONS = tuple(dict.fromkeys(k.section for k in SCHEMA))


def _keys(section: str) -> dict[str, Key]:
    return {k.name: k for k in SCHEMA if k.section == section}


def schema_key(section: str, name: str) -> Key:
    """The case-file key ``[section] name`` of :data:`SCHEMA`."""
    try:
        return _keys(section)[name]
    except KeyError:
        raise KeyError(f"no case-file key [{section}] {name}") from None


def parse_case(data: dict, where: str = "case", base: Path | None = None) -> dict[str, Any]:
    """Validated values of a parsed TOML document: {(section, key): value} of the keys given."""
    values: dict[tuple[str, str], Any] = {}
    for section, table in data.items():
        if section not in FILE_SECTIONS:
            raise CaseError(
                f"{where}: unknown section [{section}] (allowed: {', '.join(FILE_SECTIONS)})"
            )
        if not isinstance(table, dict):
            raise CaseError(f"{where}: {section} must be a [{section}] table, got {table!r}")
        keys = _keys(section)
        for name, value in table.items():
            if name not in keys:
                raise CaseError(
                    f"{where}: unknown key [{section}] {name} (allowed: {', '.join(keys)})"
                )
            values[(section, name)] = keys[name].check(value, where)

    # checks between keys of the file (the rules between fields are the sections' own: to_case)
    def get(s, k):
        return values.get((s, k), next(x.default for x in SCHEMA if (x.section, x.name) == (s, k)))

    if ("packing", "file") in values:
        given = [
            k
            for k in ("particles", "r_min", "r_max", "seed", "fraction")
            if ("packing", k) in values
        ]
        if given:
            raise CaseError(
                f"{where}: [packing] file and [packing] {given[0]} exclude each other (the file "
                "gives the spheres; the other keys drive the generator)"
            )
        path = Path(values[("packing", "file")])
        if not path.is_absolute() and base is not None:
            path = base / path
        if not path.is_file():
            raise CaseError(
                f"{where}: [packing] file = {values[('packing', 'file')]!r}: no such file ({path})"
            )
        values[("packing", "file")] = str(path)
    control = [k for (section, k) in values if section == "control" and k != "path"]
    if get("control", "path") == "none" and control:
        raise CaseError(
            f"{where}: [control] {control[0]} needs a [control] path (pressure or triaxial)"
        )
    for owner, keys in PATH_FIELDS.items():
        stray = [k for k in keys if k in control and get("control", "path") != owner]
        if stray:
            raise CaseError(f"{where}: [control] {stray[0]} belongs to path = {owner!r}")
    stress_path(values, where)  # the rules between the path's keys
    return values


def _read_toml(path: Path) -> dict:
    """The parsed TOML of a case file (CaseError if missing or not TOML)."""
    if not path.is_file():
        raise CaseError(f"{path}: no such case file")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{path}: not valid TOML: {err}") from None


def load_case(path: str | Path, out_dir: str | None = None) -> CompactionCase:
    """Read, validate and convert a case file (raises :class:`CaseError`)."""
    path, where = Path(path), str(path)
    data = _read_toml(path)
    values = parse_case(data, where, base=path.parent)
    return to_case(
        values, out_dir or values.get(("output", "directory")) or f"results/{path.stem}", where
    )


def tool_cases() -> dict[str, type]:
    """The tool-driven cases a case file may hold instead of a periodic compaction: one section
    alone, ``[die]`` (:class:`~mpfem_fenicsx.workflows.closed_die.ClosedDieCase`) or ``[box]``
    (:class:`~mpfem_fenicsx.workflows.box.BoxCase`), its keys the case's declared parameters
    (``ratios`` of ``[box]``: a list of three numbers)."""
    from ..workflows.box import BoxCase
    from ..workflows.closed_die import ClosedDieCase

    return {"die": ClosedDieCase, "box": BoxCase}


def tool_schema() -> tuple[Key, ...]:
    """The keys of the tool-driven cases' sections (``[die]``, ``[box]``), in order."""
    return tuple(key for name, cls in tool_cases().items() for key in declared_keys(name, cls))


def load_tool_case(path: str | Path, out_dir: str | None = None):
    """The tool-driven case of a case file holding ``[die]`` or ``[box]`` (validated like the
    others: CaseError naming the key), or None when it holds neither."""
    path, where = Path(path), str(path)
    data = _read_toml(path)
    cases = tool_cases()
    kinds = [k for k in data if k in cases]
    if not kinds:
        return None
    if len(data) > 1:
        other = next(k for k in data if k != kinds[0])
        raise CaseError(
            f"{where}: [{kinds[0]}] is a case of its own: remove [{other}] (allowed alone: "
            f"{', '.join(f'[{k}]' for k in cases)})"
        )
    kind, table = kinds[0], data[kinds[0]]
    if not isinstance(table, dict):
        raise CaseError(f"{where}: {kind} must be a [{kind}] table, got {table!r}")
    cls = cases[kind]
    keys = {k.name: k for k in declared_keys(kind, cls)}
    values: dict[str, Any] = {}
    for name, value in table.items():
        if kind == "box" and name == "ratios":
            ok = (
                isinstance(value, list)
                and len(value) == 3
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            )
            if not ok:
                raise CaseError(f"{where}: [box] ratios = {value!r} must be a list of 3 numbers")
            values[name] = tuple(float(v) for v in value)
            continue
        if name not in keys:
            allowed = ", ".join([*keys, *(["ratios"] if kind == "box" else [])])
            raise CaseError(f"{where}: unknown key [{kind}] {name} (allowed: {allowed})")
        values[name] = keys[name].check(value, where)
    values["out_dir"] = out_dir or values.get("out_dir") or f"results/{path.stem}"
    try:
        return cls(**values)
    except ValueError as err:
        message = re.sub(r"^(closed die|box): ", "", str(err))
        raise CaseError(f"{where}: [{kind}] {message}") from None


def to_case(
    values: dict[tuple[str, str], Any], out_dir: str, where: str = "case"
) -> CompactionCase:
    """A CompactionCase from validated values (defaults for the keys not given); a rule between
    fields that a section or the case checks raises CaseError naming it."""
    sections: dict[str, dict[str, Any]] = {}
    for (section, name), value in values.items():
        if section != "control":
            sections.setdefault(section, {})[name] = value
    sections.setdefault("output", {})["directory"] = out_dir
    try:
        if "material" in sections:
            sections["material"] = SECTIONS["material"](**sections["material"])
        path = stress_path(values, where)
        if path.path != "none":
            duration = sections.get("loading", {}).get(
                "duration", parameter_default(SECTIONS["loading"], "duration")
            )
            sections.setdefault("loading", {})["control"] = path.control(duration)
        return CompactionCase.build(**sections)
    except ValueError as err:  # a rule of the case classes not expressed in the schema
        raise CaseError(f"{where}: {as_key(str(err))}") from None


def as_key(message: str) -> str:
    """A section's message in the case file's words: ``packing.r_max`` -> ``[packing] r_max``."""
    return re.sub(rf"\b({'|'.join(SECTIONS)})\.(\w+)", r"[\1] \2", message)


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
    for section in FILE_SECTIONS:
        lines.append(f"[{section}]")
        for k in SCHEMA:
            if k.section == section:
                default = "(none)" if k.default is None else repr(k.default)
                lines.append(
                    f"  {k.name:<17} {k.kind.__name__:<5} default {default:<10} "
                    f"{k.allowed()}: {k.doc}"
                )
    return "\n".join(lines)


def example_case() -> str:
    """A complete, commented case file with every default (``mpfem init``)."""
    out = [
        "# mpfem case file: compaction of a periodic volume of elastoplastic particles.",
        "# Every key is optional; the values below are the defaults (the flagship demo).",
        "# Units: mm, N, MPa, s, t/mm^3. Reference: `mpfem run --help`.",
        "",
    ]
    for section in FILE_SECTIONS:
        out.append(f"[{section}]")
        for k in SCHEMA:
            if k.section != section:
                continue
            if k.default is None:
                out.append(f"{'# ' + k.name + ' = ...':<30} # {k.doc}; {k.allowed()}")
            else:
                value = (
                    ("true" if k.default else "false")
                    if k.kind is bool
                    else (f'"{k.default}"' if k.kind is str else repr(k.default))
                )
                # a [control] key needs a path, and the results folder defaults to the case file's
                # name: shown with their defaults, commented out
                comment = (
                    "# "
                    if (k.section == "control" and k.name != "path") or k.name == "directory"
                    else ""
                )
                out.append(f"{comment + k.name + ' = ' + value:<30} # {k.doc}; {k.allowed()}")
        out.append("")
    return "\n".join(out)
