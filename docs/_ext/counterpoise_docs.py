"""The generated parts of the documentation site (docs/conf.py loads this as a Sphinx extension).

- the command-line reference, from :data:`counterpoise.cli.spec.COMMANDS` (the one table of
  commands and options): :func:`cli_reference`, written to ``docs/_generated/cli.md`` and
  included by ``docs/cli.md``;
- the gallery, one page per ``problems/*.toml`` with its drawing, its summary and a link to
  its ``report.html`` from ``results/<name>/``: :func:`gallery_pages`, written to
  ``docs/gallery/`` (git-ignored); the report pages are copied into the built site
  (``<build>/results/<name>/report.html``) so that the site works opened from disk;
- the ``<a id="..."></a>`` anchors of the Markdown pages become link targets, so that a link
  ``seeds.md#rrs3`` resolves as it does on GitHub.

The generators import nothing from Sphinx, so the tests (``tests/test_docs.py``) call them
without the ``docs`` extra installed.
"""

from __future__ import annotations

import csv
import functools
import re
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10: tomli is a runtime dependency there
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
#: generated pages that are included by a committed page (not pages of their own)
GENERATED = DOCS / "_generated"
#: generated pages of their own: the gallery
GALLERY = DOCS / "gallery"

# --------------------------------------------------------------------------------------
# Markdown helpers
# --------------------------------------------------------------------------------------

_SPECIAL = re.compile(r"([\\`*_\[\]<>|#{}])")


def escape(text: str) -> str:
    """``text`` as literal Markdown text: every character Markdown could read as markup
    (emphasis, links, inline HTML, table cells...) backslash-escaped (CommonMark allows it
    before any ASCII punctuation)."""
    return _SPECIAL.sub(r"\\\1", text)


def write_if_changed(path: Path, text: str) -> bool:
    """Write ``text`` to ``path`` unless it already holds it (Sphinx then keeps its cached
    page); True when written."""
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return True


# --------------------------------------------------------------------------------------
# The command-line reference
# --------------------------------------------------------------------------------------


def _usage(command: Any) -> str:
    words = ["counterpoise", command.name, "[OPTIONS]"]
    for p in command.params:
        if not p.flags:
            words.append(p.dest.upper() + ("..." if p.many else ""))
    return " ".join(words)


def _value(p: Any) -> str:
    """What an option takes: its kind, its choices or its minimum, whether it repeats."""
    if p.kind == "flag":
        return "flag"
    kind = {"path": "path", "str": "text", "int": "integer", "float": "number"}[p.kind]
    if p.choices:
        kind = "one of " + ", ".join(f"`{c}`" for c in p.choices)
    elif p.minimum is not None:
        kind += f" ≥ {p.minimum}"
    if p.many:
        kind += ", one or more" if not p.flags else ", repeatable"
    return kind


def _default(p: Any, required: object) -> str:
    if p.default is required:
        return "required"
    if p.default is None or not p.show_default:
        return ""
    if p.kind == "flag":
        on = p.flags[0] if p.default else (p.flags[1] if len(p.flags) > 1 else "off")
        return f"`{on}`" if p.default or len(p.flags) > 1 else "off"
    return f"`{p.default}`"


def cli_reference() -> str:
    """The reference of every command and option, in Markdown, from ``cli/spec.py``."""
    from counterpoise.cli import spec

    lines = [
        "<!-- generated from src/counterpoise/cli/spec.py by docs/_ext/counterpoise_docs.py: do not edit -->",
        "",
        "`counterpoise [OPTIONS] COMMAND [ARGS]...`: " + escape(spec.DESCRIPTION),
        "",
    ]
    for command in spec.COMMANDS:
        lines += [
            f"### counterpoise {command.name}",
            "",
            escape(command.help),
            "",
            f"`{_usage(command)}`",
            "",
            "| argument or option | takes | default | what it does |",
            "|---|---|---|---|",
        ]
        for p in command.params:
            name = " / ".join(f"`{f}`" for f in p.flags) if p.flags else f"`{p.dest.upper()}`"
            lines.append(f"| {name} | {_value(p)} | {_default(p, spec.REQUIRED)} | {escape(p.help)} |")
        lines += ["| `--help` | flag | | Show this message and exit. |", ""]
    return "\n".join(lines)


@functools.lru_cache(maxsize=1)
def exports() -> dict[str, str]:
    """``counterpoise.__all__``: each name and the full name of what it is (where the API
    page documents it): ``verify_design`` is :func:`counterpoise.verify.check.verify`."""
    import counterpoise

    found = {}
    for name in counterpoise.__all__:
        obj = getattr(counterpoise, name)
        found[name] = f"{obj.__module__}.{obj.__qualname__}"
    return found


def exports_reference() -> str:
    """The table of the package's exported names, each linked to its documentation, in
    reStructuredText (the first paragraph of each docstring keeps its roles)."""
    import inspect

    import counterpoise

    lines = [
        ".. generated from counterpoise.__all__ by docs/_ext/counterpoise_docs.py: do not edit",
        "",
        ".. list-table::",
        "   :header-rows: 1",
        "   :widths: 20 30 50",
        "",
        "   * - ``from counterpoise import``",
        "     - is",
        "     - what it does",
    ]
    for name, full in exports().items():
        doc = inspect.getdoc(getattr(counterpoise, name)) or ""
        first = " ".join(doc.split("\n\n")[0].split())
        lines += [f"   * - ``{name}``", f"     - :py:obj:`{full}`", f"     - {first}"]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# The gallery
# --------------------------------------------------------------------------------------

#: summary.csv columns shown first, in this order; the other non-empty ones follow
_FIRST = ("status", "objective", "added_mass_kg", "added_inertia_kg_m2", "residual_ratio", "solver", "certificate", "parts")


def _summary(folder: Path) -> dict[str, str]:
    path = folder / "summary.csv"
    if not path.is_file():
        return {}
    with path.open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {k: v for k, v in rows[0].items() if v not in ("", None) and k != "problem"} if rows else {}


def _short(number: str) -> str:
    """A figure of summary.csv to three significant digits (the page has it in full)."""
    try:
        return f"{float(number):.3g}"
    except ValueError:
        return number


def problems() -> Iterator[tuple[Path, dict[str, Any]]]:
    """Each ``problems/*.toml`` (in name order) with its ``[problem]`` table."""
    for path in sorted((ROOT / "problems").glob("*.toml")):
        with path.open("rb") as handle:
            table = tomllib.load(handle).get("problem", {})
        yield path, table


def gallery_pages() -> dict[str, str]:
    """The gallery's pages, by file name under ``docs/gallery/``: ``index.md`` and one page
    per problem file (named after the file; its results are ``results/<problem name>/``)."""
    pages: dict[str, str] = {}
    rows = []
    for path, table in problems():
        stem, name = path.stem, str(table.get("name", path.stem))
        folder = ROOT / "results" / name
        summary = _summary(folder)
        title = str(table.get("title", ""))
        lines = [f"# {stem}", "", f"*{escape(title)}*" if title else "", ""]
        if table.get("source"):
            lines += [f"Source: {escape(str(table['source']))}", ""]
        lines += [f"Problem file: `problems/{path.name}` (below); results: `results/{name}/`.", ""]
        if (folder / "report.html").is_file():
            lines += [
                f'**<a href="../results/{name}/report.html">Open its page report.html</a>**: the whole design,'
                " with its build sheet, springs, energies and verification.",
                "",
            ]
        if (folder / "mechanism.png").is_file():
            lines += [f"```{{image}} ../../results/{name}/mechanism.png", f":alt: the mechanism of {name} with its design", "```", ""]
        if summary:
            lines += ["## Summary", "", "| `summary.csv` | |", "|---|---|"]
            keys = [k for k in _FIRST if k in summary] + [k for k in summary if k not in _FIRST]
            lines += [f"| `{k}` | {escape(summary[k])} |" for k in keys]
            lines += ["", "The columns are explained in the [tour](../tour.md#2-the-reports-column-by-column).", ""]
        else:
            lines += ["```{note}", f"Not solved yet: `make demo` writes `results/{name}/`.", "```", ""]
        if (folder / "status.txt").is_file():
            lines += ["## status.txt", "", "```text", (folder / "status.txt").read_text(encoding="utf-8").rstrip(), "```", ""]
        lines += ["## Problem file", "", f"```{{literalinclude}} ../../problems/{path.name}", ":language: toml", "```", ""]
        pages[f"{stem}.md"] = "\n".join(lines)
        rows.append(f"| [{stem}]({stem}.md) | {escape(title)} | {summary.get('status', 'not solved')} | {_short(summary.get('residual_ratio', ''))} |")
    thumbs = []
    for path, table in problems():
        name = str(table.get("name", path.stem))
        if (ROOT / "results" / name / "mechanism.png").is_file():
            status = _summary(ROOT / "results" / name).get("status", "not solved")
            thumbs.append(
                f'<a class="cp-thumb" href="{path.stem}.html"><img src="../results/{name}/mechanism.png" alt="{path.stem}" loading="lazy"/>'
                f"<span>{path.stem}</span><span>{status}</span></a>"
            )
    pages["index.md"] = "\n".join(
        [
            "# Gallery",
            "",
            "Every problem file of `problems/` as `make demo` solved it into `results/`: its drawing, its",
            "summary, its status and the link to its page `report.html`. Generated when the site is built.",
            "",
            "```{toctree}",
            ":hidden:",
            "",
            *(path.stem for path, _ in problems()),
            "```",
            "",
            '<div class="cp-gallery">',
            *thumbs,
            "</div>",
            "",
            "## Every problem",
            "",
            "| problem | what it is | status | residual ratio |",
            "|---|---|---|---|",
            *rows,
            "",
        ]
    )
    return pages


def write_generated() -> None:
    """Write the generated pages (unchanged files are left alone) and remove stale gallery pages."""
    write_if_changed(GENERATED / "cli.md", cli_reference())
    write_if_changed(GENERATED / "exports.rst", exports_reference())
    pages = gallery_pages()
    for name, text in pages.items():
        write_if_changed(GALLERY / name, text)
    for old in GALLERY.glob("*.md"):
        if old.name not in pages:
            old.unlink()


def copy_results(outdir: Path) -> None:
    """Copy each problem's ``report.html`` and ``mechanism.png`` into the built site, at
    ``<outdir>/results/<name>/`` (the gallery's links)."""
    for path, table in problems():
        name = str(table.get("name", path.stem))
        for file in ("report.html", "mechanism.png"):
            source = ROOT / "results" / name / file
            target = outdir / "results" / name / file
            if source.is_file() and not (target.is_file() and target.stat().st_mtime >= source.stat().st_mtime):
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, target)


# --------------------------------------------------------------------------------------
# Sphinx
# --------------------------------------------------------------------------------------

_ANCHOR = re.compile(r'^<a\s+(?:id|name)="([^"]+)"\s*/?>(?:</a>)?$')

#: files outside docs/ that are pages of the site, included by a page of docs/ (a link
#: `../problems/README.md` in a page goes to that page)
INCLUDED = {"problems/README": "problems", "benchmarks/README": "benchmarks"}


def _read(app: Any, doctree: Any) -> None:
    """Register each ``<a id="x"></a>`` of a page as the target ``x`` of that page (GitHub
    reads them so), and send a link to a file included as a page (:data:`INCLUDED`) to it."""
    from docutils import nodes
    from sphinx import addnodes

    env = app.env
    std = getattr(env.domains, "standard_domain", None) or env.get_domain("std")  # Sphinx >= 8.2, before
    docname = env.docname
    slugs = env.metadata[docname].setdefault("myst_slugs", {})
    for raw in doctree.findall(nodes.raw):
        match = _ANCHOR.match(raw.astext().strip())
        if match and "html" in raw.get("format", ""):
            name = match.group(1)
            # `page.md#name` from another page (myst reads the page's slugs), `#name` within it (std labels)
            slugs.setdefault(name, (raw.line, name, ""))
            std.anonlabels[name] = (docname, name)
            std.labels[name] = (docname, name, name)
    for xref in doctree.findall(addnodes.pending_xref):
        if xref.get("reftype") == "myst" and xref.get("refdomain") == "doc":
            target = Path(xref["reftarget"])
            if target.is_absolute() and target.is_relative_to(ROOT):
                xref["reftarget"] = INCLUDED.get(target.relative_to(ROOT).as_posix(), xref["reftarget"])


def _missing(app: Any, env: Any, node: Any, contnode: Any) -> None:
    """A link to an exported name that the API page does not document: a warning (an
    error under ``-W``), where Sphinx would leave it silently unlinked."""
    from sphinx.util import logging

    if node.get("refdomain") == "py" and node.get("reftarget") in exports().values():
        logging.getLogger(__name__).warning("counterpoise exports %s, which docs/api.md does not document", node["reftarget"], location=node)


def _generate(app: Any) -> None:
    write_generated()


def _copy(app: Any, exception: Exception | None) -> None:
    if exception is None and app.builder.format == "html":
        copy_results(Path(app.outdir))


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", _generate)
    app.connect("doctree-read", _read)
    app.connect("build-finished", _copy)
    app.connect("missing-reference", _missing)
    return {"version": "1", "parallel_read_safe": False, "parallel_write_safe": True}
