"""Panel layout shared by the figures: a row of panels (one per character, gait or method) and the
finish every such panel gets (title, axis labels, a small legend), so the figures of all systems
read alike."""
from __future__ import annotations

from matplotlib.figure import Figure


def panel_row(count: int, width: float, height: float):
    """(Figure, Axes array): ``count`` panels side by side, ``width`` x ``height`` inches each; one
    empty panel when ``count`` is 0, so a figure of an empty table still draws."""
    n = max(1, count)
    fig = Figure(figsize=(width * n, height))
    return fig, fig.subplots(1, n, squeeze=False)[0]


def label_panel(ax, title: str, ylabel: str, xlabel: str | None = None) -> None:
    """Title, axis labels (the x label only when given: bar panels label their ticks instead) and a
    7-point legend on one panel."""
    ax.set_title(title)
    if xlabel is not None:
        ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)
