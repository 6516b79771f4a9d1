"""The tree's rules, checked on the source: the design card's layout (``forms/`` and ``meshes/``
at the top level, installed as ``mpfem_fenicsx.forms`` / ``mpfem_fenicsx.meshes``), short
functions in the pipeline's packages, no branch on a solver's name outside the solver factory,
no private attribute of another package read. Static checks (ast): no model is built."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "mpfem_fenicsx"
#: the library's subpackages that live at the repository's top level (setup.py maps them in)
TOP_LEVEL = {"forms": ROOT / "forms", "meshes": ROOT / "meshes"}
SOLVER_NAMES = {"explicit", "implicit"}
#: the one place a solver's name picks a class or a kind
FACTORY = {PACKAGE / "solvers" / "factory.py", PACKAGE / "solvers" / "kinds.py"}


def _modules(*packages):
    """The modules of the library's ``packages`` (``"."``: all of it, top-level folders
    included)."""
    for package in packages:
        yield from sorted((PACKAGE / package).rglob("*.py"))
        if package == ".":
            for folder in TOP_LEVEL.values():
                yield from sorted(folder.rglob("*.py"))


def test_forms_and_meshes_sit_at_the_top_level_and_import_as_subpackages():
    import importlib

    for name, folder in TOP_LEVEL.items():
        assert (folder / "__init__.py").is_file() and not (PACKAGE / name).exists()
        module = importlib.import_module(f"mpfem_fenicsx.{name}")
        assert Path(module.__file__).resolve().parent == folder, (name, module.__file__)


#: the most statements a function of the pipeline's packages may hold (counted on the syntax tree:
#: the measure does not move with the formatting)
MAX_STATEMENTS = 70


def test_no_long_function_in_workflows_and_solvers():
    long = []
    for path in _modules("workflows", "solvers"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                statements = sum(isinstance(x, ast.stmt) for x in ast.walk(node)) - 1
                if statements > MAX_STATEMENTS:
                    long.append(
                        f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name} ({statements})"
                    )
    assert not long, f"functions over {MAX_STATEMENTS} statements: " + ", ".join(long)


def _compares_solver_name(node: ast.Compare) -> bool:
    """``x == "explicit"``, ``x != "implicit"``, ``x in ("implicit", "explicit")``..."""
    operands = [node.left, *node.comparators]
    for operand in operands:
        if isinstance(operand, ast.Constant) and operand.value in SOLVER_NAMES:
            return True
        if isinstance(operand, (ast.Tuple, ast.List, ast.Set)) and any(
            isinstance(e, ast.Constant) and e.value in SOLVER_NAMES for e in operand.elts
        ):
            return True
    return False


@pytest.mark.parametrize("tree", ["library", "demos"])
def test_no_branch_on_the_solver_name_outside_the_factory(tree):
    paths = _modules(".") if tree == "library" else sorted((PACKAGE.parent / "demos").glob("*.py"))
    branches = []
    for path in paths:
        if path in FACTORY:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare) and _compares_solver_name(node):
                branches.append(f"{path.name}:{node.lineno}")
    assert not branches, "solver-name comparisons (ask solvers.solver_kind instead): " + ", ".join(
        branches
    )


def test_no_private_attribute_of_another_package_read():
    """``obj._name`` where obj is not ``self`` / ``cls``: allowed inside one package only when the
    attribute is defined there (checked loosely: the name must be assigned as ``self._name`` in a
    module of the same package)."""
    defined: dict[Path, set[str]] = {}
    for path in _modules("."):
        names = defined.setdefault(path.parent, set())
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
            ):
                if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
                    names.add(node.attr)
    reads = []
    for path in _modules("."):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and not (
                    isinstance(node.value, ast.Name) and node.value.id in ("self", "cls", "np")
                )
                and node.attr not in defined.get(path.parent, set())
            ):
                reads.append(f"{path.relative_to(ROOT)}:{node.lineno} .{node.attr}")
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level >= 2:
                for alias in node.names:
                    if alias.name.startswith("_"):
                        reads.append(f"{path.relative_to(ROOT)}:{node.lineno} import {alias.name}")
    assert not reads, "private names of another package: " + ", ".join(reads)


#: the pipeline's orchestrators: they hand each stage the sections it needs
ORCHESTRATORS = {"build_compaction", "run_compaction", "__init__"}  # __init__: CompactionRun's


def test_no_stage_takes_the_whole_case():
    """A function annotated with a ``CompactionCase`` parameter is an orchestrator; every other
    stage takes the case's sections (``PackingSection``, ``SolverSection``...)."""
    whole = []
    for path in _modules("."):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                and node.name not in ORCHESTRATORS
            ):
                arguments = node.args.posonlyargs + node.args.args + node.args.kwonlyargs
                if any(
                    a.annotation is not None and "CompactionCase" in ast.unparse(a.annotation)
                    for a in arguments
                ):
                    whole.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}")
    assert not whole, "stages given the whole case (give them its sections): " + ", ".join(whole)
