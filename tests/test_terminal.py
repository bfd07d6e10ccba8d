"""Terminal output fits the terminal (issue 29.9): tables split into panels of whole columns, long
lines wrapped; 100 columns when there is no terminal."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from pkmtol.cli import main
from pkmtol.present.tables import text_table
from pkmtol.present.terminal import DEFAULT_WIDTH, FittedStream, fit_text, terminal_width

REPO = Path(__file__).resolve().parents[1]
SEED = str(REPO / "robots" / "r2rps_ups")
SMALL = ["--samples", "300", "--exact-samples", "0", "--verification-poses", "30", "--no-progress"]
COMMANDS = {
    "check": ["check", SEED, "--no-progress"],
    "errors": ["errors", SEED],
    "allocate": ["allocate", SEED, *SMALL, "--out", "{tmp}/a"],
    "sweep": ["sweep", SEED, "--vary", "reference_point.position_m[2]=0.2:0.5:2", "--out", "{tmp}/s"],
    "calibrate": [
        *("calibrate", SEED, "--set", "urdf", "--simulate", "--machines", "2", "--holdout", "20"),
        *("--poses", "25", "--random-sets", "1", "--candidates", "40", "--out", "{tmp}/c"),
    ],
    "new": ["new", "tricept", "--out", "{tmp}/n", "--no-progress"],
}


def test_no_terminal_means_100_columns(monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)
    assert terminal_width() == DEFAULT_WIDTH or terminal_width() >= 40  # a real terminal: its width
    monkeypatch.setenv("COLUMNS", "100")
    assert terminal_width() == 100


class Terminal(io.StringIO):
    """What a command prints to a terminal."""

    def isatty(self) -> bool:
        return True


def long_lines(lines: list[str]) -> list[str]:
    """The lines longer than 100 columns, except a line that is one unbreakable token (a path)."""
    return [line for line in lines if len(line) > 100 and len(line.split()) > 1]


@pytest.mark.parametrize("command", list(COMMANDS), ids=list(COMMANDS))
def test_every_line_of_piped_output_is_at_most_100_columns(command, tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("COLUMNS", raising=False)  # no terminal: 100 columns
    argv = [a.format(tmp=tmp_path) for a in COMMANDS[command]]
    assert main([*argv, "--no-progress"] if command == "sweep" else argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) > 5
    assert long_lines(lines) == []
    if command == "allocate":
        # the tolerance table (131 columns whole) is split: its second panel repeats No. and parameter
        assert sum(line.startswith("No.  parameter") for line in lines) == 2
        # the prose is wrapped with a hanging indent: the most error-sensitive point on two lines
        k = next(k for k, line in enumerate(lines) if line.startswith("most error-sensitive point"))
        assert lines[k + 1].startswith("  ") and lines[k + 1].strip()


def test_a_terminal_and_a_pipe_get_the_same_fitted_text():
    text = wide_table() + "\n" + "  note: " + " ".join(["word"] * 60) + "\n"
    piped, screen = io.StringIO(), Terminal()
    for sink in (piped, screen):
        stream = FittedStream(sink, width=100)
        stream.write(text)
        stream.flush()
    assert screen.getvalue() == piped.getvalue() == fit_text(text, 100)
    assert max(len(line) for line in piped.getvalue().splitlines()) <= 100


def test_a_word_longer_than_the_width_is_kept_whole_on_its_own_line():
    path = "/tmp/" + "x" * 120 + "/allocation.json"
    wrapped = fit_text(f"wrote {path}", 100).splitlines()
    assert wrapped == ["wrote", f"  {path}"]
    assert long_lines(wrapped) == [] and len(wrapped[1]) > 100


def wide_table() -> str:
    header = ["parameter", *(f"column {k} [mm]" for k in range(12))]
    rows = [header] + [[f"p{i}", *(f"{i * k / 7:.4f}" for k in range(12))] for i in range(5)]
    return text_table(rows)


def test_a_wide_table_is_split_into_panels_keeping_every_cell_under_its_header():
    text = wide_table()
    assert max(len(line) for line in text.splitlines()) > 100
    fitted = fit_text(text, 100)
    lines = fitted.splitlines()
    assert max(len(line) for line in lines) <= 100
    # each panel: a header repeating 'parameter', a rule, the 5 rows
    panels = fitted.split("\n\n")
    assert len(panels) >= 2
    seen = {}
    for panel in panels:
        head, rule, *rows = panel.splitlines()
        assert head.startswith("parameter") and set(rule) <= {"-", " "} and len(rows) == 5
        names = [h for h in head.split("  ") if h.strip()][1:]
        for row in rows:
            cells = row.split()
            for name, value in zip(names, cells[1:], strict=True):
                seen[(cells[0], name.strip())] = value
    for i in range(5):
        for k in range(12):
            assert seen[(f"p{i}", f"column {k} [mm]")] == f"{i * k / 7:.4f}"


def test_a_table_that_fits_is_left_alone_and_long_prose_is_wrapped_with_a_hanging_indent():
    small = text_table([["a", "b"], ["x", "1"]])
    assert fit_text(small, 100) == small
    prose = "  note: " + " ".join(["word"] * 60)
    wrapped = fit_text(prose, 50).splitlines()
    assert all(len(line) <= 50 for line in wrapped) and len(wrapped) > 3
    assert wrapped[0].startswith("  note:") and all(line.startswith("    word") for line in wrapped[1:])
    assert " ".join(w.strip() for w in wrapped).split() == prose.split()


def test_the_stream_fits_what_is_printed_in_pieces():
    sink = io.StringIO()
    stream = FittedStream(sink, width=100)
    text = wide_table()
    stream.write(text)
    assert sink.getvalue() == ""  # held until the line ends
    stream.write("\n")
    stream.write("tail without newline")
    stream.flush()
    assert sink.getvalue() == fit_text(text, 100) + "\n" + "tail without newline"


def test_a_panel_repeats_as_many_leading_columns_as_tell_the_rows_apart():
    header = ["errors", "model", *(f"statistic {k} [µm]" for k in range(8))]
    rows = [header] + [
        [e, m, *(f"{k}.00" for k in range(8))] for e in ("gaussian", "uniform") for m in ("a", "b")
    ]
    panels = fit_text(text_table(rows), 100).split("\n\n")
    assert len(panels) == 2
    for panel in panels:
        lines = panel.splitlines()
        assert lines[0].split()[:2] == ["errors", "model"]
        assert [tuple(line.split()[:2]) for line in lines[2:]] == [
            (e, m) for e in ("gaussian", "uniform") for m in "ab"
        ]
