"""Benchmark: search for a 15 s clip (450 frames) for one character on a paper-scale graph built
from the synthetic default corpus (16 sessions, ~50,000 frames, real annotations), after JIT warm-up.
Reports JAX beam search median time and compile time separately, and the DFS (paper) time.
Goal: beam < 50 ms median (paper: 1.16 s for its search).

    python experiments/bench_search.py [--cache DIR] [--windows N]
"""
import argparse
import time

import numpy as np
from _bench import REPO, timed, write

from convsynth_jax.config import compose
from convsynth_jax.evaluation.loo import annotate_corpus_cached, build_fold_graphs
from convsynth_jax.evaluation.windows import sliding_windows, window_segments
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.tasks.common import open_corpus

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    ap.add_argument("--windows", type=int, default=7)
    args = ap.parse_args()
    cfg = compose([f"cache_dir={args.cache}", "progress=false"])
    corpus = open_corpus(cfg)
    ann = annotate_corpus_cached(corpus, cfg, f"{args.cache}/loo_cache")
    held = corpus.sessions[0].name
    fg = build_fold_graphs(ann, held, cfg, f"{args.cache}/loo_cache")
    out = {}
    for role, a in ann[held].items():
        g = fg.graphs[a.character]
        wins = sliding_windows(a.motion.num_frames / 30.0)[: args.windows]
        cons = [build_constraints(window_segments(a.segments, w), window_segments(a.partner_segments, w), 450, 30.0, cfg)
                for w in wins]
        t0 = time.perf_counter()
        beam_search(g, cons[0], cfg, seed=0)
        compile_s = time.perf_counter() - t0
        beam_t, beam_ok, dfs_t, dfs_ok = [], [], [], []
        for k, c in enumerate(cons):
            for rep in range(3):
                r, t = timed(beam_search, g, c, cfg, seed=rep)
                beam_t.append(t); beam_ok.append(r.success)
            r, t = timed(stochastic_greedy_search, g, c, cfg, seed=k)
            dfs_t.append(t); dfs_ok.append(r.success)
        out[a.character] = {"graph_states": g.num_states, "graph_edges": g.num_edges,
                            "beam_first_call_s": compile_s, "beam_median_s": float(np.median(beam_t)),
                            "beam_success_rate": float(np.mean(beam_ok)), "dfs_median_s": float(np.median(dfs_t)),
                            "dfs_success_rate": float(np.mean(dfs_ok)), "windows": len(cons)}
    out["goal_beam_median_s"] = 0.05
    write("bench_search", out)
