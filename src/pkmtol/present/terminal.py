"""Terminal output that fits the terminal: tables split into column panels, long lines wrapped.

The commands print tables made by :func:`pkmtol.present.tables.text_table` (a header, a rule of
dashes, aligned rows) between lines of prose. :func:`fit_text` takes such text and returns it
with every line at most ``width`` columns:

* a table wider than ``width`` is split into panels of whole columns, one under the other; each
  panel repeats the table's first column (the row's name; and the next ones while the first
  only numbers the rows or does not tell them apart), so every row stays on one line and every
  number keeps its header; a single
  cell too wide even so is wrapped inside its column;
* any other long line (prose, notes, warnings) is wrapped at spaces with :mod:`textwrap`, its
  continuation lines indented two columns more than the line itself; a word is never broken, so a
  path or a URL longer than the width stays whole, on a line of its own.

The width is the terminal's (:func:`terminal_width`: ``shutil.get_terminal_size``, or
:data:`DEFAULT_WIDTH` = 100 columns when there is no terminal: a pipe, a log). :class:`FittedStream`
applies :func:`fit_text` to what a command prints on stdout, on a terminal and piped alike;
machine-readable output is never fitted: the JSON, CSV, Markdown and HTML files the commands write
keep their full lines, and so do the ``pkmtol: error:`` and ``pkmtol: warning:`` lines on stderr
(one line per message, for ``grep``).
"""

from __future__ import annotations

import re
import shutil
import textwrap
from typing import TextIO

#: Columns when the output is not a terminal (a pipe, a file, a test).
DEFAULT_WIDTH = 100
#: Never fit to fewer columns than this (a tiny terminal still gets readable tables).
MIN_WIDTH = 40
#: Spaces between two columns of a table.
GAP = 2

_RULE = re.compile(r"^-+(?: {2}-+)*$")


def terminal_width() -> int:
    """Columns of the terminal (``COLUMNS`` first), or :data:`DEFAULT_WIDTH` without a terminal."""
    return max(MIN_WIDTH, shutil.get_terminal_size((DEFAULT_WIDTH, 24)).columns)


def fit_text(text: str, width: int | None = None, wrap_lines: bool = True) -> str:
    r"""``text`` with its tables split into panels and its other lines wrapped to ``width`` columns.

    Args:
        text: Lines of prose and text tables (header, rule of dashes separated by two spaces,
            rows aligned to the rule).
        width: Columns (default: :func:`terminal_width`).
        wrap_lines: Also wrap the lines that are not tables (else they are left whole).

    Returns:
        The same content, no line longer than ``width`` except a single word longer than
        ``width`` (a path, say), which is kept whole on a line of its own (a table cell too wide
        for its panel is broken inside its column).

    >>> print(fit_text("name  alpha  beta\n----  -----  ----\nx         1     2", width=12))
    name  alpha
    ----  -----
    x         1
    <BLANKLINE>
    name  beta
    ----  ----
    x        2
    """
    width = terminal_width() if width is None else max(MIN_WIDTH // 4, int(width))
    lines = text.split("\n")
    out: list[str] = []
    k = 0
    while k < len(lines):
        if k + 1 < len(lines) and _RULE.match(lines[k + 1]) and lines[k].strip():
            end = k + 2
            while end < len(lines) and _is_row(lines[end], lines[k + 1]):
                end += 1
            block = lines[k:end]
            if max(len(line) for line in block) > width:
                out.extend(_fit_table(block, width))
            else:
                out.extend(block)
            k = end
            continue
        out.extend(_wrap(lines[k], width) if wrap_lines else [lines[k]])
        k += 1
    return "\n".join(out)


def _is_row(line: str, rule: str) -> bool:
    """Whether ``line`` is a row under ``rule``: not blank, no longer, spaces where the rule has gaps."""
    if not line.strip() or len(line) > len(rule):
        return False
    return all(line[i] == " " for i, ch in enumerate(rule[: len(line)]) if ch == " ")


def _wrap(line: str, width: int) -> list[str]:
    if len(line) <= width:
        return [line]
    indent = line[: len(line) - len(line.lstrip(" "))]
    return textwrap.wrap(
        line.strip(),
        width=width,
        initial_indent=indent,
        subsequent_indent=indent + "  ",
        break_long_words=False,
        break_on_hyphens=False,
    ) or [line]


def _spans(rule: str) -> list[tuple[int, int]]:
    return [(m.start(), m.end()) for m in re.finditer(r"-+", rule)]


def _fit_table(block: list[str], width: int) -> list[str]:
    """A text table (header, rule, rows) as panels of whole columns, each ≤ ``width``."""
    spans = _spans(block[1])
    rows = [[line[a:b].ljust(b - a)[: b - a] for a, b in spans] for line in [block[0], *block[2:]]]
    # a cell's text as it is aligned (column 0 left, the others right), without its padding
    cells = [[c.strip() for c in row] for row in rows]
    widths = [b - a for a, b in spans]
    # the row's name: the first column, and the second too when the first only numbers the rows
    keys = [0, 1] if len(spans) > 2 and all(row[0].isdigit() for row in cells[1:]) else [0]
    # and more columns while they do not yet tell the rows apart (errors + model, say)
    while (
        len(keys) < len(spans) - 1
        and len({tuple(row[c] for c in keys) for row in cells[1:]}) < len(cells) - 1
    ):
        if sum(widths[c] for c in [*keys, len(keys)]) + GAP * len(keys) > width // 2:
            break
        keys.append(len(keys))
    if sum(widths[c] for c in keys) + GAP * (len(keys) - 1) > width // 2:
        keys = [0]
        widths[0] = min(widths[0], width // 2)  # a long name is wrapped, half the width at most
    key_w = sum(widths[c] for c in keys) + GAP * (len(keys) - 1)
    panels: list[list[int]] = []
    current: list[int] = []
    used = key_w
    for c in range(len(keys), len(spans)):
        w = min(widths[c], max(1, width - key_w - GAP))
        if current and used + GAP + w > width:
            panels.append(current)
            current, used = [], key_w
        current.append(c)
        used += GAP + w
    if current:
        panels.append(current)
    out: list[str] = []
    for n, panel in enumerate(panels):
        if n:
            out.append("")
        cols = [*keys, *panel]
        col_w = [widths[c] if c in keys else min(widths[c], max(1, width - key_w - GAP)) for c in cols]
        for r, row in enumerate(cells):
            wrapped = [
                textwrap.wrap(row[c], width=w, break_long_words=True) or [""]
                for c, w in zip(cols, col_w, strict=True)
            ]
            for line_no in range(max(len(x) for x in wrapped)):
                parts = []
                for j, (c, w) in enumerate(zip(cols, col_w, strict=True)):
                    piece = wrapped[j][line_no] if line_no < len(wrapped[j]) else ""
                    parts.append(piece.ljust(w) if c == 0 else piece.rjust(w))
                out.append("  ".join(parts).rstrip())
            if r == 0:
                out.append("  ".join("-" * w for w in col_w))
    return out


class FittedStream:
    """A text stream that passes what is written to ``stream`` with :func:`fit_text` applied.

    Text is held until a write ends with a newline, so a table printed with one ``print`` (its
    text, then the newline) is fitted whole.

    Args:
        stream: Where the fitted text goes (``sys.stdout``).
        width: Columns (default: :func:`terminal_width`, read once).
        wrap_lines: Wrap the lines that are not tables too (default: yes, on a terminal and
            piped alike, at :data:`DEFAULT_WIDTH` without a terminal).
    """

    def __init__(self, stream: TextIO, width: int | None = None, wrap_lines: bool = True) -> None:
        self.stream = stream
        self.width = terminal_width() if width is None else width
        self.wrap_lines = wrap_lines
        self._pending = ""

    def write(self, text: str) -> int:
        """Hold ``text``; when it ends a line, write all that is held, fitted as one block."""
        self._pending += text
        if text.endswith("\n"):
            block, self._pending = self._pending[:-1], ""
            self.stream.write(fit_text(block, self.width, self.wrap_lines) + "\n")
        return len(text)

    def flush(self) -> None:
        """Write what is held (fitted) and flush ``stream``."""
        if self._pending:
            self.stream.write(fit_text(self._pending, self.width, self.wrap_lines))
            self._pending = ""
        self.stream.flush()

    def isatty(self) -> bool:
        """Whether ``stream`` is a terminal."""
        return bool(getattr(self.stream, "isatty", lambda: False)())

    def __getattr__(self, name: str) -> object:
        return getattr(self.stream, name)
