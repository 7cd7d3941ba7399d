# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Ablation results
# Leave-one-out success rates per condition, co-occurrence in synthesized motion against the held-out
# ground truth, and motion-quality metrics. Works on `cases.csv` of a main run or on the
# `all_cases.csv` of a collected multirun.

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import pandas as pd
from _paths import results_dir

from convsynth_jax.evaluation import summaries
from convsynth_jax.figures.motion_graph import ablation_figure, success_rate_figure

src = results_dir() / "cases.csv"
if not src.exists():
    src = results_dir() / "all_cases.csv"
cases = pd.read_csv(src)
rates = summaries.success_rates(cases)
rates

# %%
success_rate_figure(rates)

# %%
co = summaries.cooccurrence_by_condition(cases)
co

# %%
if not co.empty:
    ablation_figure(co)

# %%
summaries.quality_by_condition(cases)
