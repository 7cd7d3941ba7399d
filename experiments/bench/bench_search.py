"""Benchmark: search for a 15 s clip (450 frames) for one character on a paper-scale graph built
from the synthetic default corpus (16 sessions, ~50,000 states, real annotations), after JIT warm-up.
Reports the JAX beam search's median time and its first call (compile) separately, how often it
solves a window at its first temperature (without the hot retry), the cost and synthetic
transitions of its paths, and the same for the depth-first search of the paper.
Goal: beam < 50 ms median (paper: 1.16 s for its search).

    python experiments/bench/bench_search.py [--cache DIR] [--windows N] [--repeats R] [search.beam_size=...]
"""
import argparse
import pickle
import time

import numpy as np
import dataclasses


from convsynth_jax.config import default_params
from convsynth_jax.evaluation.loo import fit_fold
from convsynth_jax.evaluation.windows import sliding_windows, window_segments
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.systems.base import make_system
from convsynth_jax.api import annotated_corpus, cache_dir, REPO, timed, write_result

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    ap.add_argument("--windows", type=int, default=7)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--name", default="bench_search", help="result file name under experiments/results")
    ap.add_argument("--export", default=None, help="also write the graphs and window constraints to this pickle, "
                    "for bench_search_device.py on a machine without the corpus (e.g. a GPU box)")
    ap.add_argument("overrides", nargs="*", help="Hydra-style overrides, e.g. search.max_candidates=4096")
    args = ap.parse_args()
    params = default_params([f"cache_dir={args.cache}", "progress=false", *args.overrides])
    cfg = params.search
    first_only = dataclasses.replace(cfg, retry_temperatures=[], retry_beam_size=0)
    corpus, ann = annotated_corpus(params)
    held = corpus.sessions[0].name
    models = fit_fold(make_system(params, params.system), ann, held, "all", cache_dir(params))
    out = {"search_config": dataclasses.asdict(cfg)}
    export = {}
    for role, a in ann[held].items():
        g = models[a.character].graph
        wins = sliding_windows(a.motion.num_frames / 30.0)[: args.windows]
        cons = [build_constraints(window_segments(a.segments, w), window_segments(a.partner_segments, w), 450, 30.0, cfg)
                for w in wins]
        export[a.character] = (g, cons)
        t0 = time.perf_counter()
        beam_search(g, cons[0], cfg, seed=0)
        compile_s = time.perf_counter() - t0
        beam_t, beam_ok, first_ok, beam_cost, beam_syn = [], [], [], [], []
        dfs_t, dfs_ok, dfs_cost, dfs_syn = [], [], [], []
        for k, c in enumerate(cons):
            for rep in range(args.repeats):
                r, t = timed(beam_search, g, c, cfg, seed=rep)
                beam_t.append(t); beam_ok.append(r.success)
                if r.success:
                    beam_cost.append(r.cost); beam_syn.append(r.num_synthetic_transitions)
                first_ok.append(beam_search(g, c, first_only, seed=rep).success)
            r, t = timed(stochastic_greedy_search, g, c, cfg, seed=k)
            dfs_t.append(t); dfs_ok.append(r.success)
            if r.success:
                dfs_cost.append(r.cost); dfs_syn.append(r.num_synthetic_transitions)
        mean = lambda x: float(np.mean(x)) if x else float("nan")  # noqa: E731
        out[a.character] = {"graph_states": g.num_states, "graph_edges": g.num_edges, "windows": len(cons),
                            "beam_first_call_s": compile_s, "beam_median_s": float(np.median(beam_t)),
                            "beam_p90_s": float(np.percentile(beam_t, 90)),
                            "beam_success_rate": mean(beam_ok), "beam_success_first_temperature": mean(first_ok),
                            "beam_mean_cost": mean(beam_cost), "beam_mean_synthetic_transitions": mean(beam_syn),
                            "dfs_median_s": float(np.median(dfs_t)), "dfs_success_rate": mean(dfs_ok),
                            "dfs_mean_cost": mean(dfs_cost), "dfs_mean_synthetic_transitions": mean(dfs_syn)}
    out["goal_beam_median_s"] = 0.05
    write_result(args.name, out)
    if args.export:
        with open(args.export, "wb") as f:
            pickle.dump(({"search": out["search_config"]}, export), f)
