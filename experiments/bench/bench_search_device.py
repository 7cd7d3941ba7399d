"""Benchmark: the beam search on whatever device JAX picks (e.g. a GPU), from the graphs and window
constraints that ``bench_search.py --export FILE`` wrote, so the machine needs neither the corpus
nor Praat. Prints and writes median time, first call, success and synthetic transitions per
character and candidate budget.

    python experiments/bench/bench_search.py --cache DIR --export search_data.pkl      # where the corpus is
    python experiments/bench/bench_search_device.py search_data.pkl [--name bench_search_h100]
"""
import argparse
import pickle
import time

import jax
import numpy as np

from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.params import SearchParams
from convsynth_jax.api import write_result

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--name", default="bench_search_device")
    ap.add_argument("--budgets", default="2048,4096", help="search.max_candidates values to time")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with open(args.data, "rb") as f:
        cfg, data = pickle.load(f)
    out = {"device": str(jax.devices()[0]), "device_kind": jax.devices()[0].device_kind}
    for M in (int(x) for x in args.budgets.split(",")):
        c2 = SearchParams(**{**cfg["search"], "max_candidates": M})
        for ch, (g, cons) in data.items():
            t = time.perf_counter()
            beam_search(g, cons[0], c2, seed=0)
            first = time.perf_counter() - t
            ts, ok, ns = [], [], []
            for c in cons:
                for s in range(args.repeats):
                    t = time.perf_counter()
                    r = beam_search(g, c, c2, seed=s)
                    ts.append(time.perf_counter() - t)
                    ok.append(r.success)
                    if r.success:
                        ns.append(r.num_synthetic_transitions)
            out[f"{ch}_max_candidates_{M}"] = {
                "graph_states": g.num_states, "windows": len(cons), "first_call_s": first,
                "median_s": float(np.median(ts)), "success_rate": float(np.mean(ok)),
                "mean_synthetic_transitions": float(np.mean(ns)) if ns else float("nan")}
    write_result(args.name, out)
