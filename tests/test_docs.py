"""The documentation's generated pages (``docs/_ext/mpfem_docs.py``), checked without a Sphinx
build: the case-file reference lists every key of the schema, the history page every column,
demos in cells read as text and code, README summaries stop after their first table, and loose
docstrings come out as reStructuredText that docutils reads without a warning."""

import importlib.util
import re
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _docs_extension():
    path = ROOT / "docs" / "_ext" / "mpfem_docs.py"
    spec = importlib.util.spec_from_file_location("mpfem_docs", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


docs = _docs_extension()


def _sections(markdown: str) -> dict[str, str]:
    """Section name -> the text under its ``## `[section]``` heading."""
    parts = re.split(r"^## `\[(\w+)\]`$", markdown, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def test_casefile_reference_lists_every_schema_key_in_its_section():
    from mpfem_fenicsx.cli.casefile import SCHEMA

    sections = _sections(docs.casefile_reference(SCHEMA))
    assert list(sections) == list(dict.fromkeys(k.section for k in SCHEMA))
    missing = []
    for key in SCHEMA:
        rows = [r for r in sections[key.section].splitlines() if r.startswith(f"| `{key.name}` |")]
        expected = (docs.table_cell(key.allowed()), docs.table_cell(key.doc))
        complete = len(rows) == 1 and all(text in rows[0] for text in expected)
        if not complete:
            missing.append(f"[{key.section}] {key.name}")
    assert not missing, f"keys missing from the case-file reference: {missing}"


def test_history_page_documents_every_column():
    from mpfem_fenicsx.workflows.history_recorder import COLUMNS

    page = (ROOT / "docs" / "history.md").read_text()
    documented = set(re.findall(r"^\| `(\w+)`", page, flags=re.MULTILINE))
    # a tensor's nine columns are one row, written `X11` ... `X33`
    missing = [
        c for c in COLUMNS if c not in documented and re.sub(r"\d\d$", "11", c) not in documented
    ]
    assert not missing, f"history columns missing from docs/history.md: {missing}"


def test_a_demo_in_cells_reads_as_alternating_text_and_code(tmp_path):
    demo = tmp_path / "cells.py"
    demo.write_text(
        textwrap.dedent('''\
        # ---
        # jupyter: {}
        # ---
        # %% [markdown]
        # # A title
        # Some *text*.

        # %%
        """Only a docstring: shown as text."""

        # %%
        x = 1  # code

        # %% [markdown]
        # # A second part
        # ```bash
        # # a shell comment
        # ```
        ''')
    )
    page = docs.demo_page(demo, "../cells.py")
    assert "jupyter" not in page and page.startswith("# A title\n")
    marks = ("# A title", "Some *text*.", "Only a docstring", "```python\nx = 1")
    title, text, docstring, code = (page.index(mark) for mark in marks)
    assert title < text < docstring < code < page.index("\n## A second part")
    assert "\n# a shell comment" in page
    assert page.count("```python") == 1 and "literalinclude" not in page


def test_a_plain_demo_shows_its_docstring_and_source(tmp_path):
    demo = tmp_path / "plain.py"
    demo.write_text('"""What the demo does."""\nprint(1)\n')
    page = docs.demo_page(demo, "../plain.py")
    assert "What the demo does." in page and "{literalinclude} ../plain.py" in page
    assert {p.stem for p in docs.demo_paths()} >= {"isotropic", "simple_cubic"}


def test_readme_summary_stops_after_the_first_table_and_unlinks_files():
    readme = textwrap.dedent("""\
        # Report

        Intro, see [the runs](runs/x.csv) and [a site](https://example.org).
        ![a figure](figures/missing.png)

        | check | ours |
        |---|---|
        | a | 1 |

        ## Details

        long text
        """)
    summary = docs.readme_summary(readme)
    assert "| a | 1 |" in summary and "Details" not in summary and "# Report" not in summary
    assert "see the runs and [a site](https://example.org)" in summary
    assert "missing.png" not in summary
    kept = docs.readme_summary("![die](figures/die_sigma_m.png)\n", ROOT / "validation")
    assert kept.strip() == "![die](../validation/figures/die_sigma_m.png)"


LOOSE = """\
Summary line, sign conventions:
- a bullet whose text
  goes on, with |P|^T M |P| and sigma_vol_* columns
- another
Formulas under a line:
    u_full = P u_red + g
    r = P^T r_full
Text again, ``|x|`` kept, *emphasis* kept, *args escaped.

Returns:
    (position, *values): the crossing
"""


def _docutils_messages(text: str) -> list[str]:
    docutils_core = pytest.importorskip("docutils.core")
    import io

    stream = io.StringIO()
    settings = {"warning_stream": stream, "report_level": 2}
    docutils_core.publish_doctree(text, settings_overrides=settings)
    return [m for m in stream.getvalue().splitlines() if m.strip()]


def test_loose_docstrings_become_rst_without_warnings():
    assert _docutils_messages(LOOSE), "the sample must be invalid reStructuredText as written"
    fixed = "\n".join(docs.loose_rst(LOOSE.splitlines()))
    assert _docutils_messages(fixed) == []
    assert "Formulas under a line::" in fixed and "    u_full = P u_red + g" in fixed
    assert "``|x|``" in fixed and "*emphasis*" in fixed and r"\*args" in fixed


def test_valid_rst_is_left_as_it_is():
    valid = [
        "Title text with :func:`f` and ``code``.",
        "",
        "- one",
        "- two",
        "",
        "Example::",
        "",
        "    x = 1",
        "",
        "Done.",
    ]
    assert docs.loose_rst(valid) == valid
