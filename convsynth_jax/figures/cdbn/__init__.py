"""Figures of the CDBN evaluation (Sadoughi & Busso)."""
from .evaluation import init_ellipses_figure, states_curve_figure, trajectories_figure

__all__ = ["init_ellipses_figure", "states_curve_figure", "trajectories_figure"]
