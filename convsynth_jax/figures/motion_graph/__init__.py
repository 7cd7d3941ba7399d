"""Figures of the motion-graph system and its paper (Yang et al.): Table 1 (co-occurrence vs
chance), Figure 4 (cost histograms, fitted curves, threshold), Figure 6 (user-study shares), success
rates per condition, the co-occurrence ablation, and the main report's charts beside the paper."""
from .figure4 import figure4_figure
from .figure6 import figure6_figure
from .loo import ablation_figure, success_rate_figure
from .paper import ablation_ci_figure, success_beside_paper_figure, table1_beside_paper_figure
from .table1 import table1_figure

__all__ = ["ablation_ci_figure", "ablation_figure", "figure4_figure", "figure6_figure", "success_beside_paper_figure",
           "success_rate_figure", "table1_beside_paper_figure", "table1_figure"]
