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
# # Motion-graph statistics
# States, edges, transition-cost distribution and out-degrees of the graphs built by the main run.

# %% tags=["parameters"]
run = None  # a main run folder; None: the newest outputs/main/* of the checkout

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from _paths import reads, results_dir, show

from convsynth_jax.graph import load_graph

files = sorted(results_dir(run).glob("graph_*.npz"))
reads(*files)
graphs = {p.stem.removeprefix("graph_"): load_graph(p) for p in files}
pd.DataFrame([{"character": c, "states": g.num_states, "edges": g.num_edges,
               "synthetic_edges": int(g.synthetic.sum()), "threshold": g.meta.get("threshold"),
               "key_fraction": g.meta.get("key_fraction")} for c, g in graphs.items()])

# %%
fig, axes = plt.subplots(1, 2, figsize=(9, 3))
for c, g in graphs.items():
    e = g.edges_frame()
    axes[0].hist(e.loc[e["synthetic"], "cost"], bins=40, alpha=0.6, label=c)
    axes[1].hist(np.diff(g.indptr), bins=np.arange(0, np.diff(g.indptr).max() + 2), alpha=0.6, label=c)
axes[0].set_xlabel("synthetic transition cost"); axes[1].set_xlabel("out-degree")
axes[0].legend(); fig.tight_layout()
show(fig)
