"""Command-line options of the demos from declared parameters: type, default, choices, meaning,
unit and allowed range come from a :class:`~mpfem_fenicsx.parameters.Range` (a case field's
:func:`~mpfem_fenicsx.parameters.parameter` declaration, or a case-file key), and a refused
value exits 2 with one line naming the option, like a refused case file (argparse's own errors
print the usage too)."""

from __future__ import annotations

from typing import Any

from ..parameters import Range, parameter_default, parameter_range
from .exits import BAD_INPUT, fail


def add_range_option(parser, flag: str, name: str, allowed: Range, default: Any, help: str | None = None) -> None:
    """The option ``flag`` of ``parser``, parsed as ``allowed.kind`` and checked by ``allowed``;
    ``help`` is prepended to the range's meaning."""
    if allowed.kind is bool:
        raise ValueError(f"{name} is a switch: give the demo its own --{name} / --no-{name}")

    def value(text: str):
        try:
            parsed = {int: int, float: float, str: str}[allowed.kind](text)
        except ValueError:
            fail(BAD_INPUT, f"argument {flag}: {text!r} is not {'an integer' if allowed.kind is int else 'a number'}",
                 parser.prog)
        why = allowed.problem(parsed)
        if why is not None:
            fail(BAD_INPUT, f"argument {flag}: {flag} = {parsed!r} {why}", parser.prog)
        return parsed

    meaning = (allowed.doc if help is None else f"{help}; {allowed.doc}").replace("%", "%%")  # argparse formats help
    extent = "" if allowed.choices else f"; {allowed.allowed()}"
    parser.add_argument(flag, type=value, default=default, choices=allowed.choices,
                        metavar=None if allowed.choices else name.upper(),
                        help=f"{meaning}{extent} (default: %(default)s)")


def add_parameter_option(parser, cls: type, name: str, flag: str | None = None, default: Any = "field",
                         help: str | None = None) -> None:
    """The option of the dataclass field ``cls.name`` declared with ``parameter()`` (``flag``:
    default ``--name`` with dashes; ``default``: another default than the field's)."""
    add_range_option(parser, flag or "--" + name.replace("_", "-"), name, parameter_range(cls, name),
                     parameter_default(cls, name) if default == "field" else default, help)
