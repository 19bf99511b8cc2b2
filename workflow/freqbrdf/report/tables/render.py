"""Renderers of the tables, DataFrames of display strings: :func:`to_markdown` (hand-written:
pandas' own needs ``tabulate``), :func:`to_latex` and :func:`to_html` (pandas' Styler, which
needs ``jinja2``), and self-contained HTML pages (:func:`html_page`, styled by :data:`HTML_STYLE`)."""

from __future__ import annotations

import html
import re
import zlib
from collections.abc import Callable, Iterable

import pandas as pd
from pandas.io.formats.style import Styler

from freqbrdf.report.tables.display import MISSING, NOT_RUN


def _is_numeric(cell: str) -> bool:
    """Whether a display cell is a number (possibly with a unit or a bracketed breakdown)."""
    head = cell.split(" ")[0].rstrip("x")
    try:
        float(head)
    except ValueError:
        return False
    return True


def _right_aligned(table: pd.DataFrame) -> list[bool]:
    """Right-align columns whose filled cells are all numbers."""
    out = []
    for column in table.columns:
        cells = [str(c) for c in table[column] if str(c) not in (MISSING, NOT_RUN, "")]
        out.append(bool(cells) and all(_is_numeric(c) for c in cells))
    return out


def to_markdown(table: pd.DataFrame, title: str | None = None, caption: str | None = None) -> str:
    """A GitHub-flavoured Markdown pipe table, with a level-3 heading ``title`` and a caption paragraph.

    Cells are converted with ``str``; ``|`` is escaped.
    """

    def line(cells: Iterable[object]) -> str:
        return "| " + " | ".join(str(c).replace("|", r"\|").replace("\n", " ") for c in cells) + " |"

    rule = "|" + "|".join("---:" if right else "---" for right in _right_aligned(table)) + "|"
    lines = [f"### {title}", ""] if title else []
    lines += [line(table.columns), rule, *(line(row) for row in table.itertuples(index=False))]
    if caption:
        lines += ["", caption]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
    # In text mode with the default OT1 font encoding, < and > print as inverted ! and ?.
    "<": r"\textless{}", ">": r"\textgreater{}",
}


def latex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in str(text))


def _styler(table: pd.DataFrame, escape: Callable[[str], str]) -> Styler:
    """A Styler of the display strings, cells and headers escaped by ``escape``, without the index."""
    # Our own escapes rather than Styler's escape="latex"/"html": pandas' LaTeX
    # one leaves < and > as they are (see _LATEX_SPECIAL).
    return (Styler(table, cell_ids=False)
            .hide(axis="index")
            .format(lambda value: escape(str(value)))
            .format_index(lambda value: escape(str(value)), axis=1))


def to_latex(table: pd.DataFrame, caption: str | None = None, label: str | None = None) -> str:
    """A LaTeX ``table`` with a booktabs ``tabular`` (needs ``\\usepackage{booktabs}``).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped.
    caption, label : str, optional
        ``\\caption`` (escaped) and ``\\label`` of the float.
    """
    spec = "".join("r" if right else "l" for right in _right_aligned(table))
    # Styler writes table styles it does not know as commands: this one is \small.
    styler = _styler(table, latex_escape).set_table_styles([{"selector": "small", "props": ":;"}])
    return styler.to_latex(column_format=spec, position="ht", position_float="centering", hrules=True,
                           label=label, caption=latex_escape(caption) if caption else None, environment="table")


_VERDICT_CLASSES = {"yes": "yes", "no": "no", "within noise": "noise", "not judged": "notjudged"}


def _cell_classes(table: pd.DataFrame, verdicts: str | None) -> pd.DataFrame:
    """CSS classes of each cell: ``notrun``, the verdict (``yes``, ``no``, ``noise``, ``notjudged``) in
    column ``verdicts``, ``num``."""
    right = dict(zip(table.columns, _right_aligned(table)))

    def classes(column: str, text: str) -> str:
        verdict = _VERDICT_CLASSES.get(text, "") if column == verdicts else ""
        return " ".join(c for c in ("notrun" if text == NOT_RUN else "", verdict, "num" if right[column] else "") if c)

    return pd.DataFrame({c: [classes(c, str(v)) for v in table[c]] for c in table.columns}, index=table.index)


# Styler writes a <style> element before its table even with no styles (ours
# are classes, styled by the page's head); <style> in <body> is not valid HTML.
_EMPTY_STYLE = re.compile(r'<style type="text/css">\s*</style>\s*')


def to_html(table: pd.DataFrame, title: str | None = None, caption: str | None = None,
            verdicts: str | None = None) -> str:
    """An HTML fragment: heading, ``<table>`` and caption paragraph (styled by :data:`HTML_STYLE`).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped; numeric columns get the class ``num``.
    title, caption : str, optional
        ``<h2>`` above and a paragraph below the table.
    verdicts : str, optional
        A column of verdicts (the claims' ``holds``) whose cells get the classes ``yes``,
        ``no``, ``noise``, ``notjudged`` and ``notrun``, for colour.
        ``not run`` cells elsewhere get ``notrun`` too (greyed).
    """
    table = table.reset_index(drop=True)  # set_td_classes aligns on a unique index
    styler = _styler(table, html.escape).set_td_classes(_cell_classes(table, verdicts))
    # Element ids must differ between the tables of a page and stay put from run to run.
    content = f"{title}\n{table.to_csv()}"
    uuid = f"{zlib.crc32(content.encode()):08x}"
    parts = [f"<h2>{html.escape(title)}</h2>"] if title else []
    # A table wider than the report's frame scrolls inside its box instead of being cut off.
    parts.append(f'<div class="scroll">{_EMPTY_STYLE.sub("", styler.to_html(table_uuid=uuid)).strip()}</div>')
    if caption:
        parts.append(f'<p class="caption">{html.escape(caption)}</p>')
    return "\n".join(parts) + "\n"


HTML_STYLE = """
body { font-family: sans-serif; font-size: 13px; margin: 1.2em; color: #222; }
h1 { font-size: 20px; } h2 { font-size: 16px; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.4em 0; }
th, td { border: 1px solid #ccc; padding: 3px 7px; }
th { min-width: 4em; } td.num, td.notrun { white-space: nowrap; }
div.scroll { overflow-x: auto; max-width: 100%; }
th { background: #eef; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.yes { background: #d8f5d0; } td.no { background: #f8d0d0; } td.notrun { color: #888; }
td.noise { background: #f8f0c8; } td.notjudged { background: #e8e8e8; }
p.warning { background: #fde8c8; border: 1px solid #e0a050; padding: 0.5em; max-width: 60em; }
p.caption { max-width: 60em; color: #444; }
"""


def html_page(title: str, body: str) -> str:
    """A self-contained HTML page (inline style, no external resources)."""
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{HTML_STYLE}</style></head>\n<body>\n<h1>{html.escape(title)}</h1>\n{body}</body></html>\n")


def scoped_style(style: str, scope: str) -> str:
    """CSS rules with every selector prefixed by ``scope``; rules for ``body`` dropped."""
    rules = re.findall(r"([^{}]+)\{([^}]*)\}", style)
    return "\n".join(", ".join(f"{scope} {sel.strip()}" for sel in selectors.split(",")) + f" {{{body}}}"
                     for selectors, body in rules if selectors.strip() != "body")
