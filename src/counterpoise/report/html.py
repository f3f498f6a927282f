"""``report.html``: one self-contained page per design (docs/build.md).

The page is built from the report files themselves (their CSV text) and the PNG plots
written beside them, so it shows exactly what the folder holds, the design first: the
status line, the drawing (``mechanism.png``), the design variables, the build sheet
(``build.csv``), the spring specifications (``springs.csv``, whatever columns it has), the
energy and residual plot (``energy.png``), the verification, the tolerance report and the
payload schedule where there are some, and last the summary's solver figures and
``status.txt``. Images are inline (base64 ``data:`` URIs); the page has no script, no
external URL and no web font, and a print style sheet for A4 (fonts of 8 pt or more; a
table wider than :data:`PRINT_COLUMNS` columns printed transposed or in column groups, so
every column reaches the paper).
No solve, no plot: building the page costs only the formatting of text already made.
"""

from __future__ import annotations

import csv
import html
import io
from collections.abc import Mapping, Sequence

from ..designer.layers import Page

#: the images a page shows, in this order: (file, section title, what it shows)
IMAGES = (
    ("mechanism.png", "Drawing", "The mechanism at home (bold) and at the corners of its ranges (faint)."),
    ("energy.png", "Energy and residual", "Energies of the bodies and of the balancers, and the residual torque, along the coordinates."),
)

#: build.csv columns shown in the page's three build tables (the file has them all)
POINT_COLUMNS = ("item", "kind", "name", "frame", "x_mm", "y_mm", "z_mm", "world_x_mm", "world_y_mm", "world_z_mm", "value", "unit")
SPRING_COLUMNS = ("item", "name", "part_number", "rate_N_per_mm", "free_length_mm", "initial_tension_N", "cable_mm", "subsystem")
SPRING_RANGE_COLUMNS = (
    "item",
    "name",
    "distance_home_mm",
    "distance_min_mm",
    "distance_max_mm",
    "length_home_mm",
    "length_min_mm",
    "length_max_mm",
    "force_home_N",
    "force_min_N",
    "force_max_N",
)
ADJUSTMENT_COLUMNS = ("item", "name", "value", "unit", "range_min", "range_max", "note")

CSS = """
:root { color-scheme: light; }
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
       color: #1d232a; background: #fff; margin: 0 auto; padding: 1.2em 1.6em 3em; max-width: 1180px; }
h1 { font-size: 1.6em; margin: 0.2em 0; }
h2 { font-size: 1.25em; margin: 1.6em 0 0.5em; padding-bottom: 0.2em; border-bottom: 2px solid #d5dbe1; }
h3 { font-size: 1.05em; margin: 1.1em 0 0.4em; }
p.lead { color: #4a5560; margin: 0.2em 0 1em; }
nav { margin: 0.6em 0 1em; font-size: 0.92em; }
nav a { margin-right: 0.9em; color: #1f5fa8; text-decoration: none; }
.status { display: inline-block; padding: 0.15em 0.6em; border-radius: 0.3em; font-weight: 600; }
.status.ok { background: #dff3e3; color: #1e6b31; }
.status.bad { background: #fbe3e1; color: #9b2419; }
.wrap { overflow-x: auto; }
table { border-collapse: collapse; font-size: 0.84em; margin: 0.3em 0 0.8em; }
table.flip th:first-child { white-space: nowrap; }
caption { text-align: left; color: #4a5560; padding: 0.2em 0; }
th, td { border: 1px solid #d5dbe1; padding: 0.22em 0.5em; vertical-align: top; }
th { background: #eef2f5; text-align: left; font-weight: 600; }
td.nw { white-space: nowrap; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr:nth-child(even) td { background: #f8fafb; }
table.kv th { width: 16em; }
figure { margin: 0.6em 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #e3e7eb; }
figcaption { color: #4a5560; font-size: 0.9em; }
code, pre { font-family: ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 1em; }
pre { background: #f5f7f9; border: 1px solid #e3e7eb; padding: 0.7em; white-space: pre-wrap; font-size: 0.85em; }
.note { color: #4a5560; font-size: 0.92em; }
.print-only { display: none; }
@media print {
  @page { size: A4; margin: 12mm 10mm; }
  body { font-size: 9pt; max-width: none; padding: 0; }
  nav { display: none; }
  h1 { font-size: 14pt; }
  h2 { font-size: 11.5pt; margin-top: 1em; break-after: avoid; page-break-after: avoid; }
  h3 { font-size: 10pt; break-after: avoid; page-break-after: avoid; }
  table, table.wide { font-size: 8pt; width: auto; max-width: 100%; }
  caption, figcaption, .note, pre { font-size: 8pt; }
  th, td { padding: 0.12em 0.3em; }
  td.nw { white-space: normal; }
  th, td { overflow-wrap: break-word; }
  thead { display: table-header-group; }
  tr, img { break-inside: avoid; page-break-inside: avoid; }
  .wrap { overflow: visible; }
  figure { margin: 0.3em 0; }
  figure img { max-width: 100%; max-height: 170mm; width: auto; }
  .screen-only { display: none; }
  .print-only { display: block; }
  a { color: inherit; text-decoration: none; }
}
"""


def _rows(text: str) -> tuple[list[str], list[dict[str, str]]]:
    reader = csv.DictReader(io.StringIO(text))
    rows = list(reader)
    return list(reader.fieldnames or []), rows


def _number(cell: str) -> str | None:
    """A numeric cell shortened for reading (6 significant digits), or None if not a number."""
    try:
        value = float(cell)
    except ValueError:
        return None
    if cell.strip().lower() in ("nan", "inf", "-inf", "infinity", "-infinity"):
        return cell
    return f"{value:.6g}"


#: a table of more columns than this is marked wide on screen (springs.csv has 20 to 40)
WIDE = 12
#: columns a printed table has at most (A4 portrait at 8 pt: 190 mm of six-digit numbers, 15 mm each):
#: a wider table is laid out again for print, in a copy the screen does not show (the
#: screen keeps the one table, scrolling): transposed, one column per row, when it has at
#: most PRINT_TRANSPOSED_ROWS rows; else split into groups of columns, each repeating the
#: first PRINT_KEY_COLUMNS (the row's name)
PRINT_COLUMNS = 12
PRINT_TRANSPOSED_ROWS = 6
PRINT_KEY_COLUMNS = 2
#: text cells up to this long are kept on one line (names, part numbers); notes wrap
SHORT = 24


def _cell(cell: str) -> str:
    shown = _number(cell) if cell else None
    if shown is not None:
        return f'<td class="num">{html.escape(shown)}</td>'
    return f'<td class="nw">{html.escape(cell)}</td>' if len(cell) <= SHORT else f"<td>{html.escape(cell)}</td>"


#: a column name's unit suffix -> how a header shows it
SUFFIXES = (("_N_per_mm", " (N/mm)"), ("_kg_m2", " (kg m²)"), ("_N_m", " (N·m)"), ("_mm", " (mm)"), ("_kg", " (kg)"), ("_N", " (N)"), ("_s", " (s)"))


def label(column: str) -> str:
    """A CSV column name as a header: ``force_home_N`` -> ``force home (N)``."""
    for suffix, shown in SUFFIXES:
        if column.endswith(suffix):
            return column[: -len(suffix)].replace("_", " ") + shown
    return column.replace("_", " ")


def _plain(columns: Sequence[str], rows: Sequence[Mapping[str, str]], caption: str) -> str:
    head = "".join(f'<th title="{html.escape(c)}">{html.escape(label(c))}</th>' for c in columns)
    body = "".join("<tr>" + "".join(_cell(r.get(c, "") or "") for c in columns) + "</tr>" for r in rows)
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    wide = ' class="wide"' if len(columns) > WIDE else ""
    return f"<table{wide}>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _row_name(columns: Sequence[str], row: Mapping[str, str], index: int) -> str:
    """What a row is called in a transposed table: its first non-empty key cells."""
    name = " ".join(row.get(c, "") or "" for c in columns[:PRINT_KEY_COLUMNS]).strip()
    return name or f"row {index + 1}"


def _transposed(columns: Sequence[str], rows: Sequence[Mapping[str, str]], caption: str) -> str:
    """One column per row, one row per column: a table of few rows and many columns on paper."""
    head = '<th scope="col"></th>' + "".join(f"<th>{html.escape(_row_name(columns, r, i))}</th>" for i, r in enumerate(rows))
    body = "".join(
        f'<tr><th scope="row" title="{html.escape(c)}">{html.escape(label(c))}</th>' + "".join(_cell(r.get(c, "") or "") for r in rows) + "</tr>"
        for c in columns
    )
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    return f'<table class="flip">{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def _for_print(columns: Sequence[str], rows: Sequence[Mapping[str, str]], caption: str) -> str:
    """A table wider than :data:`PRINT_COLUMNS` as it is printed (see there)."""
    if len(rows) <= PRINT_TRANSPOSED_ROWS:
        return _transposed(columns, rows, caption)
    key, rest = list(columns[:PRINT_KEY_COLUMNS]), list(columns[PRINT_KEY_COLUMNS:])
    count = -(-len(rest) // (PRINT_COLUMNS - len(key)))  # groups needed; then of even size
    size = -(-len(rest) // count)
    out = []
    for first in range(0, len(rest), size):
        group = rest[first : first + size]
        part = f"columns {len(key) + first + 1}-{len(key) + first + len(group)} of {len(columns)}"
        out.append(_plain(key + group, rows, f"{caption} ({part})" if caption else part))
    return "".join(out)


def table(columns: Sequence[str], rows: Sequence[Mapping[str, str]], caption: str = "", drop_empty: bool = True) -> str:
    """An HTML table of ``rows`` (CSV cells) in ``columns`` order; columns empty in every row
    are left out (``drop_empty``). Headers show the CSV names with their unit in brackets.
    A table of more than :data:`PRINT_COLUMNS` columns has a second layout for paper."""
    if drop_empty:
        columns = [c for c in columns if any(r.get(c, "") for r in rows)]
    if len(columns) <= PRINT_COLUMNS:
        return f'<div class="wrap">{_plain(columns, rows, caption)}</div>'
    return (
        f'<div class="wrap screen-only">{_plain(columns, rows, caption)}</div>'
        f'<div class="wrap print-only">{_for_print(columns, rows, caption)}</div>'
    )


def csv_table(text: str, caption: str = "") -> str:
    columns, rows = _rows(text)
    return table(columns, rows, caption)


def _summary(text: str) -> str:
    _, rows = _rows(text)
    row = rows[0] if rows else {}
    body = "".join(
        f"<tr><th>{html.escape(k)}</th>{_cell(v)}</tr>" for k, v in row.items() if v not in ("", None)
    )
    return f'<div class="wrap"><table class="kv"><tbody>{body}</tbody></table></div>'


def _image(name: str, data: bytes, title: str, what: str) -> str:
    import base64  # only for a page with plots

    encoded = base64.b64encode(data).decode("ascii")
    return f'<figure><img src="data:image/png;base64,{encoded}" alt="{html.escape(title)} ({html.escape(name)})"><figcaption>{html.escape(what)} ({html.escape(name)})</figcaption></figure>'


def _build_section(text: str) -> str:
    columns, rows = _rows(text)
    points = [r for r in rows if r.get("kind") in ("spring_from", "spring_to", "pulley", "counter_mass")]
    springs = [r for r in rows if r.get("kind") == "spring"]
    adjustments = [r for r in rows if r.get("kind") == "adjustment"]
    parts = [
        '<p class="note">One row per physical item (<code>build.csv</code>, which holds every figure at 12 digits). '
        "Points: x, y, z in their own frame, and in the world at home (mm). A pulley mount: the pulley's axis at the "
        "spring's <em>from</em> point; the cable runs from the spring's moving end over the pulley to the <em>to</em> point; "
        "the spring's length is d + L0 − F0/k and it pulls k·d. Lengths and forces at home and over the workspace.</p>"
    ]
    if points:
        notes = "".join(
            f"<li><strong>{html.escape(r.get('item', ''))} {html.escape(r.get('name', ''))}</strong>: {html.escape(r.get('note', ''))}</li>"
            for r in points
            if r.get("note") and r.get("kind") != "counter_mass"
        )
        parts.append(
            "<h3>Anchor points, pulleys and counter-masses</h3>"
            + table(POINT_COLUMNS, points, "x, y, z in the named frame; world at home; value: a pulley's cable length, a counter-mass's mass")
            + (f'<ul class="note">{notes}</ul>' if notes else "")
        )
    if springs:
        notes = "".join(f"<li><strong>{html.escape(r.get('name', ''))}</strong>: {html.escape(r.get('note', ''))}</li>" for r in springs)
        parts.append(
            "<h3>Springs</h3>"
            + table(SPRING_COLUMNS, springs, "the part (empty: a designed spring), its rate, free length L0 and initial tension F0, the cable")
            + table(SPRING_RANGE_COLUMNS, springs, "the distance d of the anchors, the spring's own length and its force: at home, least and most over the workspace")
            + f'<ul class="note">{notes}</ul>'
        )
    if adjustments:
        parts.append("<h3>Adjustments</h3>" + table(ADJUSTMENT_COLUMNS, adjustments))
    return "".join(parts)


def _as_built_line(summary: str) -> str:
    """The header's line on the balancer as built (summary.csv's residual_ratio_as_built, beside
    the design's residual_ratio), and a banner when the springs are declared ideal."""
    import csv
    import io

    rows = list(csv.DictReader(io.StringIO(summary)))
    if not rows or not rows[0].get("residual_ratio_as_built"):
        return ""
    r = rows[0]
    text = f"Residual ratio {r['residual_ratio']} as designed; as built (rebuilt from build.csv with real springs) {r['residual_ratio_as_built']}"
    line = f'<p class="lead">{html.escape(text)}</p>'
    if r.get("spring_model") == "ideal":
        line = (
            '<p class="status bad">IDEAL SPRINGS: a paper\'s idealised design (zero free length, exactly the design rate). '
            "The status refers to that model; the hardware its build sheet specifies has the as-built figure.</p>" + line
        )
    return line


def report_html(name: str, title: str, status: str, texts: Mapping[str, str], images: Mapping[str, bytes], pages: Sequence[tuple[str, Page]] = ()) -> str:
    """The page of one design: ``texts`` are the report files' text (name -> text),
    ``images`` the PNG plots written beside them (name -> bytes), ``pages`` the sections the
    layers ask for their files (file name, :class:`~counterpoise.designer.layers.Page`:
    a tolerance band, a tuning procedure, a payload schedule), after the verification."""
    # the design first (drawing, variables, build items, springs), the solver's internals last:
    # on paper the first page is the drawing, not seventeen rows of solver figures
    sections: list[tuple[str, str, str]] = []  # (id, title, html)
    drawing = images.get("mechanism.png")
    if drawing is not None:
        sections.append(("drawing", IMAGES[0][1], _image("mechanism.png", drawing, *IMAGES[0][1:])))
    sections.append(("design", "Design variables", csv_table(texts.get("design.csv", ""), "design.csv: every design variable and report quantity, in the file's units")))
    if "build.csv" in texts:
        sections.append(("build", "Build sheet", _build_section(texts["build.csv"])))
    if "springs.csv" in texts:
        sections.append(("springs", "Spring specifications", csv_table(texts["springs.csv"], "springs.csv: each spring's part, lengths and forces over every checked configuration, its limits and margins; the bill of materials")))
    energy = images.get("energy.png")
    if energy is not None:
        sections.append(("energy", IMAGES[1][1], _image("energy.png", energy, *IMAGES[1][1:])))
    sections.append(("verification", "Verification", csv_table(texts.get("verification.csv", ""), "verification.csv: the largest residual of each balance condition over the checked configurations, against the largest gravity torque")))
    for file, page in sorted(pages, key=lambda item: item[1].order):
        if file in texts:
            sections.append((page.anchor, page.title, page.render(texts[file]) if page.render is not None else csv_table(texts[file], page.caption)))
    if "substitution.csv" in texts:
        sections.append(("substitution", "Substituted bodies", csv_table(texts["substitution.csv"])))
    sections.append(("summary", "Summary", _summary(texts.get("summary.csv", "")) + f"<pre>{html.escape(texts.get('status.txt', ''))}</pre>"))
    if drawing is None or energy is None:
        sections.append(("plots", "Plots", '<p class="note">The drawing and the energy plot are written by <code>counterpoise solve --plot</code>.</p>'))
    message = next((line[len("message: ") :] for line in texts.get("status.txt", "").splitlines() if line.startswith("message: ")), "")
    nav = "".join(f'<a href="#{sid}">{html.escape(t)}</a>' for sid, t, _ in sections)
    body = "".join(f'<section id="{sid}"><h2>{html.escape(t)}</h2>{content}</section>' for sid, t, content in sections)
    badge = "ok" if status == "optimal" else "bad"
    built = _as_built_line(texts.get("summary.csv", ""))
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(name)}: counterpoise report</title><style>{CSS}</style></head><body>"
        f"<header><h1>{html.escape(title or name)}</h1>"
        f'<p class="lead">Problem <code>{html.escape(name)}</code> · design <span class="status {badge}">{html.escape(status)}</span></p>'
        + (f'<p class="note">{html.escape(message)}</p>' if message else "")
        + built
        + f"<nav>{nav}</nav></header><main>{body}</main></body></html>\n"
    )
