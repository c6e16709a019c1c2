"""Figures that show themselves in a notebook.

chaplygin draws on :class:`matplotlib.figure.Figure` objects, not through pyplot,
so that no figure is left open in pyplot's global state.  Jupyter shows a bare
``Figure`` as ``<Figure size 600x500 with 1 Axes>`` unless pyplot's inline
backend has been activated; :class:`Figure` here adds a PNG representation, so
the figure displays inline with no extra step.
"""

from __future__ import annotations

from io import BytesIO

from matplotlib.figure import Figure as _Figure

__all__ = ["Figure"]


class Figure(_Figure):
    """A matplotlib ``Figure`` that Jupyter displays as a PNG."""

    def _repr_png_(self) -> bytes:
        buffer = BytesIO()
        self.savefig(buffer, format="png", dpi=100)
        return buffer.getvalue()
