"""The energy plot and the mechanism drawing are drawn once each (issue 19: ``make demo``
spends most of its time in the plots).

A figure of constrained layout used to be drawn two or three times: once to lay it out
(``bbox_inches="tight"`` runs a draw to find the box to crop to, and ``savefig`` runs a draw
without rendering before the real one while the figure has a layout engine), once to write
the PNG, and for the drawing once more before its labels were placed. Now it is laid out
without drawing (:func:`counterpoise.plots._mpl.freeze_layout`) and drawn once, into the
PNG: one ``Figure.draw`` per file. The fourbar has one scenario: one ``energy.png`` and one
``mechanism.png``, so two draws in all.
"""

from __future__ import annotations

import pytest

from conftest import solved


@pytest.fixture(scope="module")
def fourbar():
    result = solved("fourbar_springs")
    assert result.optimal, result.message
    return result


def _counting_draws(monkeypatch):
    from matplotlib.figure import Figure

    calls = []
    draw = Figure.draw

    def counted(self, renderer):
        calls.append(self)
        return draw(self, renderer)

    monkeypatch.setattr(Figure, "draw", counted)
    return calls


def test_energy_plot_is_drawn_once_per_file(fourbar, tmp_path, monkeypatch):
    from counterpoise.plots import energy_plot

    calls = _counting_draws(monkeypatch)
    paths = energy_plot(fourbar, tmp_path)
    assert [p.name for p in paths] == ["energy.png"]
    assert len(calls) == len(paths) == 1
    assert paths[0].read_bytes()[:4] == b"\x89PNG"


def test_mechanism_drawing_is_drawn_once_and_its_labels_stay_inside_their_axes(fourbar, tmp_path, monkeypatch):
    """Laid out without a draw, the label boxes (figure pixels at 100 dpi) are still inside
    the axes boxes measured at the same layout: the layout placed against is the one saved."""
    from counterpoise.plots.mechanism import design_drawing

    calls = _counting_draws(monkeypatch)
    drawing = design_drawing(fourbar, tmp_path)
    assert len(calls) == 1
    assert drawing.path.read_bytes()[:4] == b"\x89PNG"
    assert drawing.labels and drawing.axes
    for label in drawing.labels:
        x0, y0, x1, y1 = label.box
        assert any(a[0] <= x0 and a[1] <= y0 and x1 <= a[2] and y1 <= a[3] for a in drawing.axes), label
