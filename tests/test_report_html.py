"""report.html: self-contained, complete, and rendered by a real browser (headless Chromium).

The page of a catalogue design (yasir2019_hybrid_catalogue: springs.csv and tolerance.csv)
with its plots is built once per module. Static checks need nothing but Python; the browser
checks run Debian's ``chromium`` and are skipped, with the reason, where it is absent
(``.ci/run`` installs it in CI).
"""

from __future__ import annotations

import csv
import html
import io
import json
import re
import shutil
import subprocess

import pytest

from conftest import ROOT, solved

from counterpoise.report.files import write_reports

CHROMIUM = shutil.which("chromium")
NEEDS_CHROMIUM = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium is not installed (Debian package 'chromium'; .ci/run installs it in CI): no browser check"
)
#: the flags a headless Chromium needs here (run as root, offline, nothing of its own)
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--host-resolver-rules=MAP * ~NOTFOUND",  # a request that leaves the machine fails, and shows
    "--enable-logging=stderr",
    "--v=0",
    "--virtual-time-budget=5000",
)
#: the sections every page of a design with springs holds (their ids)
SECTIONS = ("summary", "drawing", "build", "springs", "energy", "verification", "tolerance", "design")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """(folder, page text) of the catalogue design, written as ``solve --plot`` writes it."""
    from counterpoise.plots import energy_plot
    from counterpoise.plots.mechanism import design_mechanism_plot

    result = solved("yasir2019_hybrid_catalogue")

    def plots(folder):
        energy_plot(result, folder)
        design_mechanism_plot(result, folder)

    folder = write_reports(result, tmp_path_factory.mktemp("html"), plots, html=True)
    return folder, (folder / "report.html").read_text(encoding="utf-8")


def test_page_is_self_contained(page):
    _, text = page
    assert text.startswith("<!DOCTYPE html>")
    assert "<script" not in text.lower() and "<link" not in text.lower() and "@import" not in text
    sources = re.findall(r'\b(?:src|href)="([^"]*)"', text)
    assert sources, "the page has its images and its table of contents"
    for s in sources:
        assert s.startswith("data:image/png;base64,") or s.startswith("#"), s[:60]
    assert "url(" not in text
    assert not re.search(r"https?://", text)


def test_page_holds_every_part(page):
    folder, text = page
    for section in SECTIONS:
        assert f'<section id="{section}">' in text, section
    assert text.count("<img ") == 2  # the drawing and the energy plot
    # the build sheet's items and the chosen part are on the page
    assert "left.pulley" in text and "counter_mass" in text
    part = next(r for r in csv.DictReader(io.StringIO((folder / "build.csv").read_text())) if r["kind"] == "spring" and r["name"] == "left")["part_number"]
    assert part and part in text
    assert "@media print" in text and "size: A4" in text


def test_page_without_plots_says_how_to_get_them(tmp_path):
    result = solved("fourbar_counter_mass")
    text = (write_reports(result, tmp_path, html=True) / "report.html").read_text(encoding="utf-8")
    assert "<img " not in text and "solve --plot" in text
    assert '<section id="build">' in text and '<section id="springs">' not in text


def _chromium(*args, cwd):
    run = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={cwd / 'profile'}", *args], capture_output=True, text=True, timeout=180, cwd=cwd)
    assert run.returncode == 0, run.stderr[-2000:]
    return run


@NEEDS_CHROMIUM
def test_page_renders_in_chromium_without_console_messages(page, tmp_path):
    """The page itself (no script of its own) logs nothing to the console and renders a
    screenshot that is not blank (more than one colour, and ink on a fair share of it)."""
    import matplotlib.image

    folder, _ = page
    shot = tmp_path / "page.png"
    run = _chromium("--window-size=1280,1600", f"--screenshot={shot}", (folder / "report.html").as_uri(), cwd=tmp_path)
    console = [line for line in run.stderr.splitlines() if ":CONSOLE" in line]
    assert console == [], console
    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[0] >= 1000 and pixels.shape[1] >= 1000
    colours = {tuple(p) for p in pixels[::7, ::7, :3].reshape(-1, 3).round(2).tolist()}
    assert len(colours) > 20  # text, tables and the drawing: many colours, not a blank page
    ink = (pixels[:, :, :3].mean(axis=2) < 0.9).mean()
    assert ink > 0.02


@NEEDS_CHROMIUM
def test_page_loads_no_external_resource_and_every_image_decodes(page, tmp_path):
    """A copy of the page with a probe (this test's script, not the page's) records, once
    loaded, how many images decoded and every resource the browser fetched."""
    folder, text = page
    probe = (
        "<script>window.addEventListener('load', () => document.body.setAttribute('data-probe', JSON.stringify({"
        "images: document.images.length,"
        "broken: [...document.images].filter(i => !i.complete || i.naturalWidth === 0).length,"
        "tables: document.querySelectorAll('table').length,"
        "requests: performance.getEntriesByType('resource').map(e => e.name)})));</script>"
    )
    copy = tmp_path / "probe.html"
    copy.write_text(text.replace("</body>", probe + "</body>"), encoding="utf-8")
    run = _chromium("--dump-dom", copy.as_uri(), cwd=tmp_path)
    found = re.search(r'data-probe="([^"]*)"', run.stdout)
    assert found, run.stdout[:500]
    seen = json.loads(html.unescape(found.group(1)))
    assert seen["images"] == 2 and seen["broken"] == 0
    assert seen["tables"] >= 7  # summary, three build tables, springs, verification, tolerance, design
    assert [r for r in seen["requests"] if not r.startswith(("data:", "file:"))] == []


def test_solve_writes_the_page_by_default_and_report_csv_leaves_it_out(tmp_path, capsys):
    """``solve`` writes report.html unless ``--report csv``; another value is refused:
    exit 2, one line, nothing written."""
    from counterpoise.cli import main

    problem = str(ROOT / "problems" / "yasir2019_counter_mass.toml")
    runs = ((tmp_path / "a", [], True), (tmp_path / "b", ["--report=csv"], False), (tmp_path / "c", ["--report", "csv"], False))
    for out, extra, page in runs:
        with pytest.raises(SystemExit) as exit_:
            main(["solve", problem, "--out", str(out), *extra])
        assert exit_.value.code == 0
        folder = out / "yasir2019_counter_mass"
        assert (folder / "build.csv").is_file() and (folder / "report.html").is_file() == page
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_:
        main(["solve", problem, "--out", str(tmp_path / "d"), "--report", "pdf"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip() == "--report: expected one of html, csv, got 'pdf'"
    assert not (tmp_path / "d").exists()


def test_page_of_a_payload_range_holds_its_schedule(tmp_path):
    """A payload range with a catalogue part (woo2019_hybrid_catalogue): the page adds the
    schedule and the tolerance report, and every report file in the folder is on it."""
    result = solved("woo2019_hybrid_catalogue")
    folder = write_reports(result, tmp_path, html=True)
    text = (folder / "report.html").read_text(encoding="utf-8")
    for section in ("summary", "build", "springs", "verification", "tolerance", "schedule", "design"):
        assert f'<section id="{section}">' in text, section
    shown = {"summary.csv": "summary", "build.csv": "build", "springs.csv": "springs", "verification.csv": "verification",
             "tolerance.csv": "tolerance", "schedule.csv": "schedule", "design.csv": "design"}
    assert sorted(p.name for p in folder.glob("*.csv")) == sorted(shown)
    # the adjustments set per payload (the counter-mass levers dL_c1, dL_c2) have their table
    assert "<h3>Adjustments</h3>" in text and "dL_c1" in text and "dL_c2" in text


# -- on paper (issue 32): A4, fonts of 8 pt or more, every column, the design first ------


@pytest.fixture(scope="module")
def designed_page(tmp_path_factory):
    """(folder, page text) of a design with designed springs (fourbar_springs): springs.csv
    has some forty columns, the stresses, allowables, safety factors and mass last."""
    result = solved("fourbar_springs")
    folder = write_reports(result, tmp_path_factory.mktemp("designed"), html=True)
    return folder, (folder / "report.html").read_text(encoding="utf-8")


def _print_block(text):
    """The body of the page's ``@media print { ... }`` rule."""
    start = text.index("@media print {") + len("@media print {")
    depth, i = 1, start
    while depth:
        depth += {"{": 1, "}": -1}.get(text[i], 0)
        i += 1
    return text[start : i - 1]


def _without_screen_copies(text):
    """The page as printed: the screen-only copies of wide tables left out."""
    return re.sub(r'<div class="wrap screen-only">.*?</table></div>', "", text, flags=re.S)


@pytest.mark.parametrize("which", ["page", "designed_page"])
def test_print_rules_put_every_column_on_paper_in_fonts_of_8_pt(which, request):
    """Static (no browser): the print style sheet sets every font size in pt, none below 8;
    every table printed has at most PRINT_COLUMNS columns; every column of springs.csv (the
    widest table) is among the printed tables' headers; the design comes before the
    summary's solver figures."""
    from counterpoise.report.html import PRINT_COLUMNS

    folder, text = request.getfixturevalue(which)
    rules = _print_block(text)
    assert "size: A4" in rules
    sizes = re.findall(r"font-size:\s*([0-9.]+)(\w+)", rules)
    assert sizes and all(unit == "pt" and float(value) >= 8 for value, unit in sizes), sizes
    printed = _without_screen_copies(text)
    for head in re.findall(r"<thead><tr>(.*?)</tr></thead>", printed, flags=re.S):
        assert head.count("<th") <= PRINT_COLUMNS, head[:200]
    header = (folder / "springs.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    titles = set(re.findall(r'<th[^>]* title="([^"]*)"', printed))
    rows = list(csv.DictReader(io.StringIO((folder / "springs.csv").read_text(encoding="utf-8"))))
    shown = [c for c in header if any(r[c] for r in rows)]
    assert [c for c in shown if c not in titles] == []
    if which == "designed_page":
        assert {"body_stress_MPa", "hook_bending_stress_MPa", "allowable_body_MPa", "safety_factor_nominal_rate", "safety_factor_upper_rate", "mass_g"} <= titles
    order = re.findall(r'<section id="([a-z]+)">', text)
    first = ["drawing"] if "drawing" in order else []  # the designed page is written without plots
    design = [order.index(x) for x in (*first, "design", "build", "springs")]
    assert design == sorted(design) and design[-1] < order.index("verification") < order.index("summary") == len(order) - 1 - ("plots" in order)


@NEEDS_CHROMIUM
@pytest.mark.parametrize("which", ["page", "designed_page"])
def test_printed_tables_fit_an_a4_page(which, request, tmp_path):
    """The browser lays the page out with its print rules (applied to the screen, at the
    width of an A4 page inside its margins: 190 mm = 718 CSS px) and a probe (this test's
    script) reports every displayed table that reaches past that width, every text in a
    font below 8 pt, and the columns on show."""
    folder, text = request.getfixturevalue(which)
    probe = (
        "<script>window.addEventListener('load', () => {"
        "const width = document.documentElement.clientWidth;"
        "const shown = e => e.offsetParent !== null || getComputedStyle(e).position === 'fixed';"
        "const wide = [...document.querySelectorAll('table')].filter(t => shown(t) && t.getBoundingClientRect().right > width + 0.5)"
        ".map(t => (t.caption ? t.caption.textContent : t.rows[0].textContent).slice(0, 80));"
        "const small = []; const walk = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);"
        "while (walk.nextNode()) { const e = walk.currentNode.parentElement;"
        " if (!walk.currentNode.textContent.trim() || !shown(e)) continue;"
        " const px = parseFloat(getComputedStyle(e).fontSize); if (px < 8 * 96 / 72 - 0.01) small.push(e.tagName + ' ' + px); }"
        "const columns = [...new Set([...document.querySelectorAll('th[title]')].filter(shown).map(th => th.title))];"
        "document.body.setAttribute('data-probe', JSON.stringify({width, wide, small: small.slice(0, 20), columns}));});</script>"
    )
    copy = tmp_path / "print.html"
    copy.write_text(text.replace("@media print {", "@media all {").replace("</body>", probe + "</body>"), encoding="utf-8")
    run = _chromium("--window-size=718,1200", "--dump-dom", copy.as_uri(), cwd=tmp_path)
    found = re.search(r'data-probe="([^"]*)"', run.stdout)
    assert found, run.stdout[:500]
    seen = json.loads(html.unescape(found.group(1)))
    assert 700 <= seen["width"] <= 720
    assert seen["wide"] == [] and seen["small"] == []
    rows = list(csv.DictReader(io.StringIO((folder / "springs.csv").read_text(encoding="utf-8"))))
    assert [c for c in rows[0] if any(r[c] for r in rows) and c not in seen["columns"]] == []


def test_the_header_gives_the_balancer_as_built_and_says_ideal_springs(tmp_path):
    """summary.csv's residual_ratio_as_built beside residual_ratio, at the top of the page; a
    paper's idealised design (yasir2019_hybrid: its springs declared ideal) says so there."""
    ideal = write_reports(solved("yasir2019_hybrid"), tmp_path / "ideal", html=True)
    text = (ideal / "report.html").read_text(encoding="utf-8")
    header = text[: text.index("<nav>")]
    assert "as built (rebuilt from build.csv with real springs)" in header and "IDEAL SPRINGS" in header
    real = write_reports(solved("fourbar_springs"), tmp_path / "real", html=True)
    header = (real / "report.html").read_text(encoding="utf-8").split("<nav>")[0]
    assert "as built (rebuilt from build.csv with real springs)" in header and "IDEAL SPRINGS" not in header
