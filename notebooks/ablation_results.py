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
# `all_cases.csv` of a collected leave-one-out sweep (`convsynth task=collect task.dir=...`).
# A *window* is one test case (both characters); a *character-window* is one character in one window.

# %% tags=["parameters"]
run = None  # a main run or a collected sweep folder; None: the newest outputs/main/* of the checkout

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import pandas as pd
from _paths import reads, results_dir, show

from convsynth_jax.evaluation import summaries
from convsynth_jax.figures.motion_graph import ablation_figure, success_rate_figure

src = results_dir(run) / "cases.csv"
if not src.exists():
    src = results_dir(run) / "all_cases.csv"
reads(src)
cases = pd.read_csv(src)
if "status" in cases:
    cases = cases[cases["status"] != "error"]
rates = summaries.success_rates(cases)
rates

# %%
show(success_rate_figure(rates))

# %%
co = summaries.cooccurrence_by_condition(cases)
co

# %%
if not co.empty:
    show(ablation_figure(co))

# %%
summaries.quality_by_condition(cases)
