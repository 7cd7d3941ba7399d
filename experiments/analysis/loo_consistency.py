"""Does the leave-one-out ground truth reproduce Table 1? (docs/decisions.md#eq-1s-idle-threshold-belongs-to-a-recording)

Table 1 (over whole recordings) beside the ground-truth co-occurrence summed over every window of
every leave-one-out fold, per character x hypothesis, counted by the one measure the project uses
(Eq. 1 thresholds of the recording); and, as the negative control, the same windows with Eq. 1
recomputed over each window (the old code path). A row passes when the count differences stay within
what cutting the recordings into windows explains and the summed rate lies inside Table 1's 95%
Wilson interval (see ``convsynth_jax/evaluation/consistency.py``). No synthesis is run.

Writes experiments/results/loo_consistency.{json,md,csv} and loo_consistency.png.

    python experiments/analysis/loo_consistency.py [--cache DIR] [--corpus synthetic_tiny] [--sessions N]
"""
import argparse
import time

import numpy as np
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from _bench import RESULTS, write

from convsynth_jax.annotate.cache import annotate_corpus_cached
from convsynth_jax.config import default_params
from convsynth_jax.evaluation.consistency import consistency_table, loo_ground_truth
from convsynth_jax.evaluation.summaries import to_markdown
from convsynth_jax.figures import save_figure
from convsynth_jax.stats.cooccurrence import cooccurrence_table
from convsynth_jax.api import open_corpus
from convsynth_jax.utils import atomic_path, write_text_atomic


def figure(tables: dict):
    """Table 1 rate with its Wilson interval beside the summed leave-one-out rates, per character."""
    from matplotlib.figure import Figure

    first = next(iter(tables.values()))
    chars = list(dict.fromkeys(first["character"]))
    fig = Figure(figsize=(5.5 * len(chars), 3.4))
    axes = fig.subplots(1, len(chars), squeeze=False)[0]
    for ax, c in zip(axes, chars):
        g = first[first["character"] == c]
        x = np.arange(len(g))
        ax.errorbar(x - 0.2, 100 * g["table1_rate"], yerr=100 * np.vstack([g["table1_rate"] - g["ci_low"],
                    g["ci_high"] - g["table1_rate"]]), fmt="o", color="k", capsize=3, label="Table 1 (95% Wilson)")
        for i, (name, t) in enumerate(tables.items()):
            gg = t[t["character"] == c]
            ax.plot(x + 0.1 + 0.2 * i, 100 * gg["loo_rate"], "s" if i == 0 else "x", label=f"LOO GT, {name}")
        ax.set_xticks(x, g["hypothesis"], rotation=20)
        ax.set_ylabel("co-occurrence rate (%)")
        ax.set_title(c)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="data_cache", help="cache_dir (corpus and annotations)")
    ap.add_argument("--corpus", default=None, help="corpus config, e.g. synthetic_tiny (default: the default corpus)")
    ap.add_argument("--sessions", type=int, default=None, help="first N sessions only")
    a = ap.parse_args()
    over = [f"cache_dir={a.cache}", "progress=false"] + ([f"corpus={a.corpus}"] if a.corpus else [])
    params = default_params(over)
    t0 = time.perf_counter()
    corpus = open_corpus(params)
    from convsynth_jax.api import cache_dir

    ann = annotate_corpus_cached(corpus, params.annotate, params.fps, cache_dir(params), progress=False)
    if a.sessions:
        ann = {k: ann[k] for k in list(ann)[: a.sessions]}
    t1 = time.perf_counter()
    table1 = cooccurrence_table(ann, params.annotate, params.stats, params.seed)
    t2 = time.perf_counter()
    conf = float(params.stats.confidence)
    tables = {scope: consistency_table(table1, loo_ground_truth(ann, params, scope), confidence=conf)
              for scope in ("recording", "window")}
    t3 = time.perf_counter()
    res = tables["recording"]
    old = tables["window"]
    both = res.merge(old[["character", "hypothesis", "loo_matched", "loo_total", "loo_rate", "passes"]],
                     on=["character", "hypothesis"], suffixes=("", "_window_threshold"))
    name = "loo_consistency" + (f"_{a.corpus}" if a.corpus else "") + (f"_{a.sessions}s" if a.sessions else "")
    RESULTS.mkdir(parents=True, exist_ok=True)
    with atomic_path(RESULTS / f"{name}.csv") as tmp:
        both.to_csv(tmp, index=False)
    write_text_atomic(RESULTS / f"{name}.md", to_markdown(both.drop(columns=["ci_low", "ci_high"]), ".3g"))
    save_figure(figure({"recording thresholds": res, "window thresholds (old)": old}), RESULTS / f"{name}.png", dpi=120)
    write(name, {
        "corpus": a.corpus or "default", "sessions": len(ann), "all_pass": bool(res["passes"].all()),
        "old_code_path_passes": bool(old["passes"].all()),
        "failing_rows_old": [f"{r.character} {r.hypothesis}" for r in old.itertuples() if not r.passes],
        "rows": [{"row": f"{r.character} {r.hypothesis}", "table1": f"{r.table1_matched}/{r.table1_total}",
                  "table1_ci95": [round(r.ci_low, 3), round(r.ci_high, 3)],
                  "loo_gt": f"{r.loo_matched}/{r.loo_total}",
                  "loo_gt_window_threshold": f"{o.loo_matched}/{o.loo_total}",
                  "allowance_matched": int(r.edge_affected + r.duplicated + r.uncovered),
                  "passes": bool(r.passes), "passes_window_threshold": bool(o.passes)}
                 for r, o in zip(res.itertuples(), old.itertuples())],
        "seconds": {"annotation": t1 - t0, "table1": t2 - t1, "loo_ground_truth_both_scopes": t3 - t2},
    })


if __name__ == "__main__":
    main()
