"""Small HTML pieces for the rich displays (``_repr_html_``) of Jupyter.

A leaf module: it imports no layer of chaplygin, so that every layer may use it.  Every piece of
text passes through :func:`escape` (system and parameter names come from users' files); the
only markup is what these functions write.  Mathematics is LaTeX inside ``$…$``, which Jupyter
typesets with MathJax.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Iterable, Sequence
from typing import Any

__all__ = ["escape", "fields", "heading", "latex_text", "math", "png", "table"]


def escape(text: Any) -> str:
    """``str(text)`` with ``& < > " '`` escaped."""
    return html.escape(str(text), quote=True)


def math(latex: str, *, display: bool = False) -> str:
    """LaTeX as ``$…$`` (``$$…$$`` with ``display``), escaped: MathJax reads the same formula."""
    fence = "$$" if display else "$"
    return f"{fence}{escape(latex)}{fence}"


def latex_text(text: str) -> str:
    r"""``text`` as LaTeX ``\text{…}``, its special characters (``\ { } $ & # ^ _ % ~``) escaped."""
    special = {"\\": r"\textbackslash{}", "^": r"\^{}", "~": r"\~{}"}
    out = "".join(special.get(c, "\\" + c if c in "{}$&#_%" else c) for c in text)
    return r"\text{" + out + "}"


def heading(text: str) -> str:
    """A bold title line (escaped)."""
    return f"<p><strong>{escape(text)}</strong></p>"


def table(rows: Iterable[Sequence[str]], header: Sequence[str] = ()) -> str:
    """An HTML table of ``rows``, whose cells are HTML already (escape text with :func:`escape`).

    ``header`` (plain text, escaped here) becomes the first row of ``<th>`` cells.
    """
    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell}</td>" for cell in row) + "</tr>" for row in rows)
    return f"<table>{f'<tr>{head}</tr>' if head else ''}{body}</table>"


def fields(items: Iterable[tuple[str, str]]) -> str:
    """A two-column table: a label (plain text, escaped) and its value (HTML)."""
    rows = "".join(
        f"<tr><th style='text-align:left'>{escape(label)}</th><td>{value}</td></tr>" for label, value in items
    )
    return f"<table>{rows}</table>"


def png(fig: Any, *, alt: str = "figure", dpi: int = 72) -> str:
    """An ``<img>`` with the matplotlib figure ``fig`` embedded as base64 PNG; ``fig`` is closed.

    Works with a bare ``matplotlib.figure.Figure`` (drawn by Agg, no pyplot needed); a figure
    that pyplot manages is closed there too, so that a notebook does not show it a second time.
    """
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=dpi)
    finally:
        if getattr(fig.canvas, "manager", None) is not None:
            import matplotlib.pyplot as plt

            plt.close(fig)
    data = base64.b64encode(buffer.getvalue()).decode("ascii")
    return f"<img src='data:image/png;base64,{data}' alt='{escape(alt)}'/>"
