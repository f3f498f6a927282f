"""The documentation: README's first screen and its example, the generated command-line
reference against ``counterpoise --help``, the gallery, the layer order wherever a page writes
it, and the set-up of the site (``make docs``; docs/development.md, "The documentation site").

The generators of docs/_ext/counterpoise_docs.py import nothing from Sphinx: they are called
here without the ``docs`` extra; the Sphinx build itself runs in ``make docs`` (CI: ``.ci/run``).
"""

from __future__ import annotations

import importlib.util
import re
import sys

import pytest

from conftest import ROOT, run_cli
from test_api import LAYERS

README = (ROOT / "README.md").read_text(encoding="utf-8")


def _generators():
    """docs/_ext/counterpoise_docs.py, imported by its path (docs/ is no package)."""
    name = "counterpoise_docs"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "_ext" / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


# --------------------------------------------------------------------------------------
# README
# --------------------------------------------------------------------------------------


def _readme_python() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README, flags=re.S)
    assert len(blocks) == 1, "README has one python example"
    return blocks[0]


def test_readme_is_short_and_its_first_screen_says_what_a_newcomer_asked_for():
    """Issue 33: at most 150 lines; first what it does, the lamp's drawing, the two commands,
    the page to open, then a 25-line example, then the index of the docs."""
    lines = README.splitlines()
    assert len(lines) <= 150, len(lines)

    def line_of(text: str) -> int:
        found = [i for i, line in enumerate(lines) if text in line]
        assert found, text
        return found[0]

    what = line_of("designs **gravity balancers**")
    drawing = line_of("](results/lamp_catalogue/mechanism.png)")
    demo, test = line_of("make demo"), line_of("make test")
    page = line_of("open `results/lamp_catalogue/report.html`")
    example = line_of("```python")
    index = line_of("## Documentation")
    assert what < drawing < demo < test < page < example < index
    assert page < 25  # the first screen: a terminal's height
    assert len(_readme_python().strip().splitlines()) <= 25
    assert (ROOT / "results" / "lamp_catalogue" / "mechanism.png").is_file()


def test_readme_example_runs(tmp_path, monkeypatch, capsys):
    """The example as a reader runs it from the repository's root: it solves the lamp, writes
    its reports and designs the pendulum (M b = m r; b = 1/sqrt(w) minimises M + w M b², so
    b = 1/4 m and M = 0.8 × 0.3 / 0.25 = 0.96 kg)."""
    (tmp_path / "problems").symlink_to(ROOT / "problems")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(_readme_python(), "README.md", "exec"), namespace)  # noqa: S102 - our own documentation
    printed = capsys.readouterr().out.splitlines()
    assert namespace["lamp"].status.value == "optimal" and printed[0].startswith("optimal - ")
    assert (tmp_path / "my-results" / "lamp_catalogue" / "report.html").is_file()
    assert printed[1].startswith("optimal ")
    m, r, w = 0.8, 0.3, 16.0
    values = {s.variable: v for s, v in namespace["result"].solution.values.items()}
    assert values["b"] == pytest.approx(1 / w**0.5, rel=1e-7)
    assert values["M"] * values["b"] == pytest.approx(m * r, rel=1e-9)


def test_readme_indexes_every_page_of_the_docs():
    """Each page of docs/ is in README's index (docs/index.md, problems.md and benchmarks.md
    are the site's own pages: the index links problems/README.md and benchmarks/README.md)."""
    site_only = {"index", "problems", "benchmarks"}
    pages = sorted(p.stem for p in (ROOT / "docs").glob("*.md") if p.stem not in site_only)
    missing = [p for p in pages if f"](docs/{p}.md)" not in README]
    assert not missing, missing
    assert "](problems/README.md)" in README and "](benchmarks/README.md)" in README


def test_the_site_has_every_page_in_a_toctree():
    """Sphinx warns of a page in no toctree (an error under make docs' -W): listed here too, to
    be told without the docs extra."""
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^([\w/-]+)$", "\n".join(re.findall(r"```\{toctree\}\n(.*?)```", index, flags=re.S)), flags=re.M))
    pages = {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"}
    assert pages <= listed, pages - listed
    assert "gallery/index" in listed


# --------------------------------------------------------------------------------------
# The command-line reference
# --------------------------------------------------------------------------------------


def _flat(text: str) -> str:
    """Help text as words: rich's box characters and the line breaks of wrapping removed."""
    return " ".join(re.sub(r"[│╭╮╰╯─┃┏┓┗┛━]", " ", text).split())


def _unescape(markdown: str) -> str:
    return re.sub(r"\\(.)", r"\1", markdown)


def _reference() -> dict[str, dict]:
    """The generated reference read back: command -> {"help", "options": {name: help}}."""
    text = _generators().cli_reference()
    commands: dict[str, dict] = {}
    for section in re.split(r"^### counterpoise ", text, flags=re.M)[1:]:
        name, _, body = section.partition("\n")
        paragraphs = [p.strip() for p in body.split("\n\n") if p.strip()]
        options = {}
        for row in re.findall(r"^\| (`[^|]*`(?: / `[^|]*`)?) \|.*\| ((?:[^|\\]|\\.)*) \|$", body, flags=re.M):
            names = tuple(re.findall(r"`([^`]+)`", row[0]))
            options[names] = _unescape(row[1]).strip()
        commands[name.strip()] = {"help": _unescape(paragraphs[0]), "options": options}
    return commands


def _help(*args: str, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", "400")  # no wrapping: rich reads the width from COLUMNS
    monkeypatch.setenv("TERMINAL_WIDTH", "400")
    run = run_cli(*args, "--help")
    assert run.returncode == 0, run.stderr
    return run.stdout


def _listed_commands(top_level_help: str) -> list[str]:
    """The command names of ``counterpoise --help``: the first word of each line of its
    Commands section (plain or in a rich panel), up to the section's end."""
    lines = top_level_help.splitlines()
    start = next(i for i, line in enumerate(lines) if re.search(r"\bCommands\b", line))
    names = []
    indent = None
    for line in lines[start + 1 :]:
        plain = re.sub(r"[│╭╮╰╯─┃┏┓┗┛━]", " ", line)
        words = plain.split()
        if not words:
            break
        here = len(plain) - len(plain.lstrip())
        indent = here if indent is None else indent
        if here == indent:  # a command's line; deeper lines continue its wrapped help
            names.append(words[0])
    return names


def test_cli_reference_lists_the_commands_of_counterpoise_help(monkeypatch):
    reference = _reference()
    top = _help(monkeypatch=monkeypatch)
    assert _listed_commands(top) == list(reference)
    flat = _flat(top)
    for name, command in reference.items():
        assert _flat(command["help"]) in flat, name


def test_cli_reference_has_every_option_of_each_commands_help_with_its_help(monkeypatch):
    """Both ways: every argument and option of ``counterpoise COMMAND --help`` is in the
    reference, every one of the reference is in the help, each with the same help text."""
    for name, command in _reference().items():
        text = _help(name, monkeypatch=monkeypatch)
        flat = _flat(text)
        assert _flat(command["help"]) in flat, name
        documented = {n for names in command["options"] for n in names if n.startswith("--")}
        shown = set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", text))
        assert documented == shown, (name, documented ^ shown)
        for names, help_text in command["options"].items():
            assert _flat(help_text) in flat, (name, names)
            for argument in (n for n in names if not n.startswith("-")):
                assert re.search(rf"\b{argument}\b", flat, flags=re.I), (name, argument)


def test_cli_reference_is_the_table(monkeypatch):
    """Every entry of ``cli/spec.py``'s COMMANDS, and nothing else, with its help."""
    from counterpoise.cli.spec import COMMANDS

    reference = _reference()
    assert list(reference) == [c.name for c in COMMANDS]
    for c in COMMANDS:
        expected = {p.flags or (p.dest.upper(),): p.help for p in c.params} | {("--help",): "Show this message and exit."}
        assert reference[c.name]["options"] == expected, c.name


# --------------------------------------------------------------------------------------
# The gallery and the API page
# --------------------------------------------------------------------------------------


def test_gallery_has_a_page_per_problem_file_with_its_drawing_summary_and_report():
    pages = _generators().gallery_pages()
    stems = sorted(p.stem for p in (ROOT / "problems").glob("*.toml"))
    assert sorted(pages) == sorted([f"{s}.md" for s in stems] + ["index.md"])
    lamp = pages["lamp_catalogue.md"]
    status = (ROOT / "results" / "lamp_catalogue" / "summary.csv").read_text(encoding="utf-8").splitlines()[1].split(",")[1]
    assert "../../results/lamp_catalogue/mechanism.png" in lamp
    assert f"| `status` | {status} |" in lamp
    assert 'href="../results/lamp_catalogue/report.html"' in lamp
    assert "literalinclude} ../../problems/lamp_catalogue.toml" in lamp
    assert all(f"({s}.md)" in pages["index.md"] for s in stems)


def test_gallery_page_of_a_problem_not_yet_solved(tmp_path, monkeypatch):
    """A problem file added without its results (the lead regenerates results/): its page
    says so, with no drawing and no link that would break the site."""
    docs = _generators()
    (tmp_path / "problems").mkdir()
    (tmp_path / "problems" / "new_arm.toml").write_text('[problem]\nname = "new_arm"\ntitle = "A new arm"\n', encoding="utf-8")
    monkeypatch.setattr(docs, "ROOT", tmp_path)
    page = docs.gallery_pages()["new_arm.md"]
    assert "Not solved yet: `make demo` writes `results/new_arm/`." in page
    assert "mechanism.png" not in page and "report.html" not in page and "A new arm" in page


def test_api_page_documents_the_module_of_every_exported_name():
    """Each name of ``counterpoise.__all__`` is documented where it is defined (the built site
    also fails on an exported name without documentation: docs/_ext, ``_missing``)."""
    page = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    documented = set(re.findall(r"^\.\. automodule:: ([\w.]+)$", page, flags=re.M))
    exports = _generators().exports()
    assert set(exports) == set(__import__("counterpoise").__all__)
    missing = {name: full for name, full in exports.items() if full.rsplit(".", 1)[0] not in documented}
    assert not missing, missing


# --------------------------------------------------------------------------------------
# The layer order and the set-up
# --------------------------------------------------------------------------------------

_ITEM = r"`{0,2}(\w+)`{0,2}(?:\s*\([^()]*\))?"
_CHAIN = re.compile(rf"{_ITEM}(?:\s*→\s*{_ITEM})+")


def _layer_chains(text: str) -> list[list[str]]:
    """Each written chain of layers ``a → b → ...`` that starts at the first layer (a name may
    be in backquotes and followed by a remark in brackets)."""
    chains = []
    for match in _CHAIN.finditer(text):
        names = [re.match(_ITEM, part.strip()).group(1) for part in match.group(0).split("→")]
        if names[0] == LAYERS[0]:
            chains.append(names)
    return chains


def test_every_written_layer_order_is_the_one_the_layer_test_enforces():
    """The order is written where a reader meets it: docs/development.md (which names the
    test's list), the package's docstring and docs/layout.md. Each agrees with ``LAYERS``."""
    required = [ROOT / "docs" / "development.md", ROOT / "docs" / "layout.md", ROOT / "src" / "counterpoise" / "__init__.py"]
    others = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "problems" / "README.md"]
    for path in dict.fromkeys(required + others):
        chains = _layer_chains(path.read_text(encoding="utf-8"))
        if path in required:
            assert chains, f"{path.relative_to(ROOT)} does not write the layer order"
        for chain in chains:
            assert chain == LAYERS, f"{path.relative_to(ROOT)}: {' → '.join(chain)}"


def test_the_chain_reader_sees_a_wrong_order():
    """The check above can fail: a docstring-style chain with one layer missing, one swapped."""
    written = "``model`` (typed problem) → ``catalogue`` → ``io`` (files) → ``mechanics`` → cli"
    assert _layer_chains(written) == [["model", "catalogue", "io", "mechanics", "cli"]]


def test_make_docs_builds_the_site_with_warnings_as_errors_from_the_docs_extra():
    """The tools are a ``docs`` extra, never runtime dependencies; ``make docs`` installs the
    extra on its own stamp and fails on any warning; CI builds the site after the tests; the
    built site and the generated pages are not committed."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    tools = {re.match(r"[\w-]+", r).group(0) for r in project["optional-dependencies"]["docs"]}
    assert {"sphinx", "myst-parser", "furo"} <= tools
    assert not tools & {re.match(r"[\w-]+", r).group(0) for r in project["dependencies"]}
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    rule = re.search(r"^docs: (.*)\n((?:\t.*\n)+)", makefile, flags=re.M)
    assert rule is not None and rule.group(1) == "$(DOCSTAMP)"
    assert "-m sphinx -b html -W --keep-going" in rule.group(2) and "docs docs/_build/html" in rule.group(2)
    assert "$(call install,-e '.[docs]')" in re.search(r"^\$\(DOCSTAMP\): \$\(STAMP\)\n((?:\t.*\n)+)", makefile, flags=re.M).group(1)
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert ci.index("make docs") > ci.index("make test")
    ignored = (ROOT / ".gitignore").read_text(encoding="utf-8").splitlines()
    assert {"docs/_build/", "docs/_generated/", "docs/gallery/"} <= set(ignored)
