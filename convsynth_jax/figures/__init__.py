"""One function per paper artifact, each pure data -> matplotlib Figure (object-oriented API, no
global pyplot state, no backend switching at import):

* Table 1 (co-occurrence vs chance): :func:`table1_figure`
* Figure 4 (cost histograms, fitted curves, threshold): :func:`figure4_figure`
* Figure 6 (user-study forced-choice shares): :func:`figure6_figure`
* success rates per condition: :func:`success_rate_figure`; ablation (co-occurrence per
  condition vs ground truth): :func:`ablation_figure`

Tables 2 and 3 are tables (``convsynth_jax.evaluation.summaries``). Tasks write the data, then
call these; ``experiments/*.py`` redraw them from the written tables.
"""
from .figure4 import figure4_figure
from .figure6 import figure6_figure
from .loo import ablation_figure, success_rate_figure
from .table1 import table1_figure

__all__ = ["ablation_figure", "figure4_figure", "figure6_figure", "success_rate_figure", "table1_figure"]
