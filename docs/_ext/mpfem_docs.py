"""Pages of the documentation generated at build time, from the repository's own sources.

Nothing here is hand-copied: each page is rebuilt from what the code declares or the files hold,
so the documentation cannot drift from them.

- :func:`casefile_reference`: the case-file reference, one table per section, from the schema of
  the case files (items with ``section``, ``name``, ``kind``, ``default``, ``doc`` and
  ``allowed()``).
- :func:`demo_page`: a demo's page; a literate demo (``# %%`` cells) becomes alternating text and
  code, any other its module docstring and its source.
- :func:`loose_rst`: docstrings, written for humans in a loose reStructuredText, made valid
  (the API pages and the demos' docstrings are read through it).
- :func:`readme_summary`: the opening of a README up to the end of its first table's section,
  with links to files outside the documentation turned into plain text.

The Sphinx hook :func:`generate` writes them before the sources are read (``builder-inited``);
a file is rewritten only when its text changes, so an incremental build stays incremental.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

#: the repository (this file is docs/_ext/mpfem_docs.py)
ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
GENERATED = DOCS / "_generated"
DEMO_PAGES = DOCS / "demos"

_KIND_WORDS = {int: "integer", float: "number", bool: "true / false", str: "string"}


# --- the case-file reference ------------------------------------------------------------------


def table_cell(text: str) -> str:
    """``text`` made safe inside a Markdown table cell (no pipe, no line break)."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _toml_value(value) -> str:
    """A default as it is written in a case file (TOML), or a dash when the key has none."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f'`"{value}"`'
    return f"`{value!r}`"


def casefile_reference(schema) -> str:
    """The case-file reference in Markdown: per section, in schema order, a heading ``[section]``
    and one table row per key (key, type, default, allowed values, meaning with unit)."""
    sections: dict[str, list] = {}
    for key in schema:
        sections.setdefault(key.section, []).append(key)
    lines = []
    for section, keys in sections.items():
        lines += [
            f"## `[{section}]`",
            "",
            f"({len(keys)} keys)",
            "",
            "| key | type | default | allowed | meaning (unit) |",
            "|---|---|---|---|---|",
        ]
        for key in keys:
            kind = _KIND_WORDS.get(key.kind, key.kind.__name__)
            lines.append(
                f"| `{key.name}` | {kind} | {table_cell(_toml_value(key.default))} "
                f"| {table_cell(key.allowed())} | {table_cell(key.doc)} |"
            )
        lines.append("")
    return "\n".join(lines)


# --- the demos --------------------------------------------------------------------------------

_CELL = re.compile(r"^# %%(.*)$")


def is_literate(source: str) -> bool:
    """Whether a demo is written in the percent format (cells opened by ``# %%`` lines)."""
    return any(_CELL.match(line) for line in source.splitlines())


def _docstring_only(code: str) -> str | None:
    """The docstring of a code cell that holds nothing else, else None."""
    try:
        body = ast.parse(code).body
    except SyntaxError:
        return None
    value = body[0].value if len(body) == 1 and isinstance(body[0], ast.Expr) else None
    only_string = isinstance(value, ast.Constant) and isinstance(value.value, str)
    return ast.get_docstring(ast.Module(body=body, type_ignores=[])) if only_string else None


def _cells(source: str) -> list[tuple[str, str]]:
    """The cells of a percent-format file as (``"markdown"`` or ``"code"``, text); a leading
    commented header (e.g. jupytext's ``# ---`` metadata) before the first cell is dropped."""
    cells: list[tuple[str, list[str]]] = []
    for line in source.splitlines():
        match = _CELL.match(line)
        if match:
            cells.append(("markdown" if "[markdown]" in match.group(1) else "code", []))
        elif cells:
            cells[-1][1].append(line)
    out = []
    for kind, lines in cells:
        if kind == "markdown":
            text = "\n".join(
                line[2:] if line.startswith("# ") else line.lstrip("#") for line in lines
            )
        else:
            text = "\n".join(lines)
        if text.strip():
            out.append((kind, text.strip("\n")))
    return out


def demo_page(path: Path, source_link: str) -> str:
    """The Markdown page of the demo at ``path``; ``source_link``: the path to the demo from the
    page's folder. A literate demo: its markdown cells as text, its code cells as code (a cell
    holding only a docstring as text). Any other demo: its module docstring, then its source."""
    source = path.read_text()
    name = path.stem
    lines = [
        f"# `{name}.py`",
        "",
        f"Source: {{download}}`demos/{name}.py <{source_link}>`. Run it from the repository "
        f"root with `.venv/bin/python demos/{name}.py --help` for its options.",
        "",
    ]
    if is_literate(source):
        cells = _cells(source)
        if cells and cells[0][0] == "markdown" and cells[0][1].startswith("# "):
            title, _, rest = cells[0][1].partition("\n")
            lines = [title, ""] + lines[1:]
            cells[0] = ("markdown", rest.strip("\n"))
        for kind, text in cells:
            docstring = _docstring_only(text) if kind == "code" else None
            if kind == "markdown":
                lines += [_demote(text), ""]
            elif docstring is not None:
                lines += [_rst_block(docstring), ""]
            else:
                lines += ["```python", text, "```", ""]
        return "\n".join(lines)
    docstring = ast.get_docstring(ast.parse(source)) or "(no module docstring)"
    lines += [
        _rst_block(docstring),
        "",
        "## Source",
        "",
        f"```{{literalinclude}} {source_link}",
        ":language: python",
        ":linenos:",
        "```",
        "",
    ]
    return "\n".join(lines)


def _demote(markdown: str) -> str:
    """Level-1 headings of a text cell made level 2 (the page has its title), code fences left."""
    out, fenced = [], False
    for line in markdown.splitlines():
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
        out.append("#" + line if not fenced and line.startswith("# ") else line)
    return "\n".join(out)


def _rst_block(docstring: str) -> str:
    """A docstring as a MyST block of reStructuredText, read like the API's (:func:`loose_rst`)."""
    body = "\n".join(loose_rst(docstring.splitlines()))
    fence = "````" if "```" in body else "```"
    return f"{fence}{{eval-rst}}\n{body}\n{fence}"


def demo_paths(root: Path = ROOT) -> list[Path]:
    """Every demo: the Python files directly under ``demos/``, by name."""
    return sorted((root / "demos").glob("*.py"))


# --- README summaries -------------------------------------------------------------------------

_LINK = re.compile(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)")
_HEADING = re.compile(r"^(#{1,6})\s")


def _unlink(text: str, folder: Path | None = None) -> str:
    """Links to anything but a web address become their text (a relative link of a README points
    at a repository file the documentation does not hold). An image of the README's ``folder``
    is kept, its path made relative to a page of ``docs/``; any other image is dropped."""

    def plain(match: re.Match) -> str:
        image, label, target = match.groups()
        if target.startswith(("http://", "https://")):
            return match.group(0)
        if image and folder is not None and (folder / target).is_file():
            return f"![{label}](../{(folder / target).resolve().relative_to(ROOT).as_posix()})"
        return "" if image else label

    return _LINK.sub(plain, text)


def readme_summary(text: str, folder: Path | None = None) -> str:
    """The opening of a README: everything before the first level-2 heading that follows its
    first table (the whole text if none), its title dropped, headings kept at level 3 or below,
    repository links made plain text (images of ``folder``, the README's, kept)."""
    lines = text.splitlines()
    seen_table = False
    kept = []
    for i, line in enumerate(lines):
        if line.startswith("|"):
            seen_table = True
        if seen_table and line.startswith("## ") and i > 0:
            break
        kept.append(line)
    if kept and kept[0].startswith("# "):
        kept = kept[1:]
    out = []
    for line in kept:
        match = _HEADING.match(line)
        if match:
            line = "#" * max(3, len(match.group(1)) + 1) + line[len(match.group(1)) :]
        out.append(line)
    return _unlink("\n".join(out), folder).strip("\n") + "\n"


def whole_readme(text: str, folder: Path | None = None) -> str:
    """A whole README for a page of its own: its headings kept, repository links made plain
    (images of ``folder``, the README's, kept)."""
    return _unlink(text, folder)


# --- docstrings in loose reStructuredText -----------------------------------------------------

_BULLET = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s+")
#: inline literals, roles and interpreted text: left as they are
_INLINE_MARKUP = re.compile(r"(``.+?``|:[\w:.-]+:`[^`]+`|`[^`]+`_{0,2})")
_TRAILING_UNDERSCORE = re.compile(r"(?<=\w)_(?![\w`])")
_EMPHASIS_RUN = re.compile(r"\*+")
_START_BEFORE = " \t'\"([{<-/:"


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _escape_stars(text: str) -> str:
    """Escape the asterisks that would open an emphasis never closed on the line (``*args``,
    ``a *b``), keeping ``*word*`` and ``**word**``."""
    out, pos = [], 0
    for match in _EMPHASIS_RUN.finditer(text):
        start, end = match.span()
        before = text[start - 1] if start else " "
        after = text[end] if end < len(text) else " "
        opens = before in _START_BEFORE and not after.isspace()
        close = r"\S" + re.escape(match.group()) + r"(?=[\s.,;:!?)'\"\]}>-]|$)"
        closed = opens and re.search(close, text[end:]) is not None
        out.append(text[pos:start])
        out.append(match.group() if (closed or not opens) else "\\*" * len(match.group()))
        pos = end
    return "".join(out) + text[pos:]


def _escape(line: str) -> str:
    """Outside inline literals and roles: ``|`` (no substitutions here), an underscore ending a
    word (no reference targets here) and unclosed emphasis made literal characters."""
    parts = _INLINE_MARKUP.split(line)
    for i in range(0, len(parts), 2):  # the even parts are plain text
        text = parts[i].replace("|", "\\|")
        text = _TRAILING_UNDERSCORE.sub(r"\\_", text)
        parts[i] = _escape_stars(text)
    return "".join(parts)


def loose_rst(lines: list[str]) -> list[str]:
    """A docstring written for humans in loose reStructuredText, made valid reStructuredText
    with the same look: a block indented under a line of text becomes a literal block (the
    formulas), a list or block followed at once by text gets the blank line it needs, and the
    characters docutils would take for markup (``|``, a word's trailing ``_``, an unclosed
    ``*``) stay characters. Lines already valid are unchanged."""
    out: list[str] = []
    literal_base = None  # inside a literal block: the indentation of the text that opened it
    opener = None  # indentation of the last line ending with "::" (a literal block or directive)
    run_bullet = None  # indentation of the last bullet marker in the current run of lines
    for line in lines:
        blank = not line.strip()
        ind = _indent(line)
        if literal_base is not None:
            if blank or ind > literal_base:
                out.append(line)
                continue
            literal_base = None
            if out and out[-1].strip():
                out.append("")
        if blank:
            out.append(line)
            run_bullet = None
            continue
        prev = out[-1] if out and out[-1].strip() else None
        if opener is not None and ind > opener:  # the block a "::" line opened
            if prev is not None:
                out.append("")
            out.append(line)
            literal_base, opener = opener, None
            continue
        opener = ind if line.rstrip().endswith("::") else None
        bullet = _BULLET.match(line)
        if prev is not None and ind > _indent(prev):
            in_item = run_bullet is not None and ind == _content_indent(out, run_bullet)
            field = prev.lstrip().startswith(":")
            if not in_item and not field and not bullet:
                out[-1] = prev.rstrip() + (":" if prev.rstrip().endswith(":") else " ::")
                out.append("")
                out.append(line)
                literal_base, opener = _indent(prev), None
                run_bullet = None
                continue
        elif (
            prev is not None
            and not bullet
            and (ind < _indent(prev) or (run_bullet is not None and ind <= run_bullet))
        ):
            out.append("")
            run_bullet = None
        if bullet and prev is not None and run_bullet is None and out[-1].strip():
            out.append("")  # a list right under a line of text
        if bullet:
            run_bullet = ind
        out.append(_escape(line))
    return out


def _content_indent(out: list[str], bullet_indent: int) -> int:
    """The indentation of the text of the last bullet item at ``bullet_indent`` in ``out``."""
    for line in reversed(out):
        match = _BULLET.match(line)
        if match and _indent(line) == bullet_indent:
            return match.end()
    return bullet_indent + 2


def _process_docstring(app, what, name, obj, options, lines) -> None:
    """autodoc hook: read every docstring as loose reStructuredText (:func:`loose_rst`)."""
    lines[:] = loose_rst(lines)


# --- the Sphinx hook --------------------------------------------------------------------------


def _write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless it already holds it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _figures(folder: Path, relative: str) -> str:
    """A figure directive per PNG of ``folder`` (``relative``: the folder from the page)."""
    blocks = []
    for png in sorted(folder.glob("*.png")):
        blocks += [
            f"```{{figure}} {relative}/{png.name}",
            ":width: 100%",
            "",
            f"`{png.relative_to(ROOT)}`",
            "```",
            "",
        ]
    return "\n".join(blocks) if blocks else "(no figure yet)\n"


def generate(app=None) -> None:
    """Write the generated pages: the case-file reference, the README summaries and figure
    lists (``docs/_generated/``), the flagship figure snippet and one page per demo
    (``docs/demos/<demo>.md``, stale ones removed)."""
    from mpfem_fenicsx.cli.casefile import SCHEMA, tool_schema

    _write(GENERATED / "casefile_keys.md", casefile_reference(SCHEMA))
    _write(GENERATED / "casefile_tool_keys.md", casefile_reference(tool_schema()))
    for name, readme in (
        ("validation", ROOT / "validation" / "README.md"),
        ("bench", ROOT / "bench" / "README.md"),
    ):
        text = readme.read_text() if readme.exists() else f"(no {name}/README.md)\n"
        _write(GENERATED / f"{name}_summary.md", readme_summary(text, readme.parent))
        _write(GENERATED / f"{name}_full.md", whole_readme(text, readme.parent))
    _write(
        GENERATED / "validation_figures.md",
        _figures(ROOT / "validation" / "figures", "../validation/figures"),
    )
    flagship = DOCS / "figures" / "flagship.png"
    _write(
        GENERATED / "flagship.md",
        "```{figure} figures/flagship.png\n:width: 100%\n\nThe flagship demo "
        "(`demos/isotropic.py`): compaction curve and deformed particles.\n```\n"
        if flagship.exists()
        else "",
    )
    pages = set()
    for path in demo_paths():
        page = DEMO_PAGES / f"{path.stem}.md"
        _write(page, demo_page(path, f"../../demos/{path.name}"))
        pages.add(page)
    for stale in DEMO_PAGES.glob("*.md"):
        if stale.name != "index.md" and stale not in pages:
            stale.unlink()


def setup(app):
    """Sphinx extension: generate the pages when the builder starts, read docstrings as loose
    reStructuredText."""
    app.connect("builder-inited", generate)
    app.connect("autodoc-process-docstring", _process_docstring)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
