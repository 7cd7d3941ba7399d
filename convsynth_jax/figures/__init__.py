"""Figures: one function per paper artifact, each pure data -> matplotlib Figure (object-oriented
API, no global pyplot state, no backend switching at import), grouped per system:

* :mod:`.motion_graph`: Table 1, Figure 4, Figure 6 (user study), success rates, the co-occurrence
  ablation and the beside-the-paper charts of the main report (Yang et al.);
* :mod:`.cdbn`: the CDBN evaluation (Sadoughi & Busso): Fig. 6 state ellipses, Fig. 9 model
  selection curves, head trajectories;
* :mod:`.walktalk`: the Walk the Talk evaluation: stroke peak vs gait phase, elbow bend, contact
  sheet of one splice.

A task writes the data as tables, calls the figure function, and writes the figure with
:func:`save_figure` (the one save helper); ``experiments/paper/*.py`` redraw the figures from the
written tables the same way. Tables 2 and 3 are tables (``convsynth_jax.evaluation.summaries``).
"""
from .save import save_figure

__all__ = ["save_figure"]
