"""Benchmark: motion-graph construction at scale (docs/scale.md) and the beam search on each graph.

Databases from ``task=make_scale_db`` (graph/scale_db.py) of 54,067 frames (the Bandai clips), 216,268
(the clips and their mirrored, warped and mirrored-warped variants) and 1,000,000 frames (plus
synthetic-corpus sessions and their variants). For each, in a fresh process: the sharded
construction (graph/stream.py) from the memory-mapped database folder into an empty build folder;
wall time, CPU time, peak RSS (the process's, database pages included), states and edges. Then the
exponent of wall time against frames (least squares on the logs), and on each graph, loaded
memory-mapped, the beam search (with look-ahead, default search config) of the first 15 s window of
each character of synthetic session 1 (its planted conversation): the first call and the median
of the warm calls (wall and process CPU time), the same with the dense look-ahead
(``search.lookahead_pass=dense``) and without one, and the look-ahead kernel alone in both passes
(time, frames computed densely or by changed states, changed states per frame, equal bits). Goals:
1M-frame construction <= 600 s, peak RSS <= 8 GB, warm search <= 1 s per character.

    python experiments/bench/bench_scale.py [--frames 54067,216268,1000000] [--work DIR] [--repeats 3]
        [--graph graph.max_out_degree=32] [--skip-search] [--search-only FRAMES,...] [--name bench_scale]

``--graph``: graph overrides for every build; ``--search-only``: only the searches, on the graphs
already built for those sizes (e.g. 54067,1000000). Databases are made once into ``--work`` (default data_cache/scale) and
reused. Writes experiments/results/<name>.json (+ manifest) and <name>.md.
"""
import argparse
import dataclasses
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from convsynth_jax.api import REPO, SHARED_DATA, peak_rss_mb, write_result, write_result_markdown
GOALS = {"construction_1m_s": 600.0, "peak_rss_mb": 8192.0, "warm_search_s": 1.0}



def child(*args):
    t = time.perf_counter()
    r = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True)
    if r.returncode != 0:
        frames = next((int(a) for a in args[1:2] if a.isdigit()), None)
        return {"error": r.stderr[-3000:], "wall_s": time.perf_counter() - t, "frames": frames,
                "returncode": r.returncode}
    return json.loads(r.stdout.strip().splitlines()[-1])


def make_db(frames: int, folder: Path) -> dict:
    from convsynth_jax.graph.scale_db import ScaleDBParams, make_scale_database
    from convsynth_jax.graph.store import save_database

    root = SHARED_DATA / "bandai2" / "bvh"
    t = time.perf_counter()
    db = make_scale_database(ScaleDBParams(frames=frames, seed=0, bandai_root=str(root) if root.is_dir() else None))
    save_database(db, folder)
    return {"frames": db.num_frames, "clips": len(db.clip_names), "seconds": time.perf_counter() - t,
            **db.meta["scale_db"], "peak_rss_mb": peak_rss_mb()}


def build(folder: Path, out: Path, overrides: list) -> dict:
    from convsynth_jax.config import default_params
    from convsynth_jax.graph.store import load_database
    from convsynth_jax.graph.stream import build_graph_sharded

    params = default_params(["progress=false", *overrides]).graph
    shutil.rmtree(out, ignore_errors=True)
    t, c = time.perf_counter(), time.process_time()
    db = load_database(folder)
    g = build_graph_sharded(db, params, out)
    m = g.meta
    return {"frames": db.num_frames, "wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c,
            "peak_rss_mb": peak_rss_mb(), "key_states": m["num_key_states"], "threshold": m["threshold"],
            "states_before_scc": m["num_states_before_scc"], "edges_before_scc": m["num_edges_before_scc"],
            "states": m["num_states"], "edges": m["num_edges"], "synthetic_edges": m["num_synthetic_edges"],
            "timings": m["timings"], "kernel": m["kernel"], "scc_warning": m.get("scc_warning", "")}


def timed(fn, repeats: int):
    """(wall times, process CPU times, last result) of ``repeats`` calls of ``fn``."""
    wall, cpu, r = [], [], None
    for rep in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        r = fn(rep)
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return wall, cpu, r


def lookahead_kernels(g, c, params, repeats: int) -> dict:
    """The look-ahead kernel alone, dense and changed-state (search.lookahead_pass), warm: wall and CPU
    medians, how each frame was computed, the changed states per frame, and whether the bits are equal."""
    import jax

    from convsynth_jax.search.beam import _prepare, padded_inputs
    from convsynth_jax.search.feasible import SparseCapacity, feasibility

    prep = _prepare(g, int(params.max_degree))
    inputs = padded_inputs(c)
    S = prep.device.state_code.shape[0]
    out, bits = {}, {}
    for name, cap in (("dense", None), ("changed", SparseCapacity(max(S // 32, 1)))):
        jax.block_until_ready(feasibility(prep, c, inputs, cap, stats=True))
        wall, cpu, r = timed(lambda _: jax.block_until_ready(feasibility(prep, c, inputs, cap, stats=True)), repeats)
        feas, ok, (kinds, nchg) = (np.asarray(r[0]), bool(r[1]), tuple(np.asarray(x) for x in r[2]))
        real = kinds >= 0
        bits[name] = feas
        out[name] = {"warm_median_s": float(np.median(wall)), "warm_cpu_median_s": float(np.median(cpu)),
                     "solvable": ok, "frames_dense": int((kinds == 0).sum()), "frames_changed": int((kinds == 1).sum()),
                     "frames_fixed_point": int((kinds == 2).sum()),
                     "changed_states_per_frame": {q: float(np.percentile(nchg[real], p)) for q, p in
                                                  (("p10", 10), ("median", 50), ("p90", 90), ("max", 100))}}
    out["bits_equal"] = bool(np.array_equal(bits["dense"], bits["changed"]))
    return out


def search(out: Path, repeats: int) -> dict:
    import pandas as pd

    from convsynth_jax.config import default_params
    from convsynth_jax.evaluation.windows import sliding_windows, window_segments
    from convsynth_jax.graph.scale_db import synthetic_clips
    from convsynth_jax.graph.store import load_graph_folder
    from convsynth_jax.search.beam import beam_search
    from convsynth_jax.search.constraints import build_constraints

    params = default_params(["progress=false"]).search
    t = time.perf_counter()
    g = load_graph_folder(out / "graph", mmap=True, verify=False)
    load_s = time.perf_counter() - t
    res = {"states": g.num_states, "edges": g.num_edges, "load_s": load_s, "lookahead_pass": params.lookahead_pass,
           "characters": {}}
    # the planted conversation of synthetic session 1 (its segments do not depend on the calibration)
    clips = synthetic_clips(1, 0, 106.0, 30.0, calibrate=False)
    win = sliding_windows(106.0)[0]
    cols = ["kind", "start", "end", "peak"]
    for clip in clips:
        load0 = os.getloadavg()
        own, partner = (pd.DataFrame(list(s), columns=cols) for s in clip.segments)
        c = build_constraints(window_segments(own, win), window_segments(partner, win), 450, 30.0, params)
        t = time.perf_counter()
        first = beam_search(g, c, params, seed=0)
        first_s = time.perf_counter() - t
        warm, warm_cpu, r = timed(lambda rep: beam_search(g, c, params, seed=rep + 1), repeats)
        # the same search with the dense look-ahead (search.lookahead_pass=dense), compiled first
        dense = dataclasses.replace(params, lookahead_pass="dense")
        beam_search(g, c, dense, seed=0)
        warm_d, cpu_d, r_d = timed(lambda rep: beam_search(g, c, dense, seed=rep + 1), repeats)
        # the same window without the look-ahead (search.lookahead=false), compiled first
        nola = dataclasses.replace(params, lookahead=False)
        beam_search(g, c, nola, seed=0)
        warm_nola, _, r_n = timed(lambda rep: beam_search(g, c, nola, seed=rep + 1), repeats)
        res["characters"][clip.name.split("_")[-1]] = {
            "no_lookahead_warm_median_s": float(np.median(warm_nola)), "no_lookahead_success": bool(r_n.success),
            "first_call_s": first_s, "warm_s": warm, "warm_median_s": float(np.median(warm)),
            "warm_cpu_s": warm_cpu, "warm_cpu_median_s": float(np.median(warm_cpu)),
            "dense_warm_median_s": float(np.median(warm_d)), "dense_warm_cpu_median_s": float(np.median(cpu_d)),
            "dense_success": bool(r_d.success),
            "same_path_as_dense": bool(r.success and r_d.success and np.array_equal(r.path, r_d.path)),
            "success_first": bool(first.success), "success_warm": bool(r.success), "constraints": int(r.constraints_total),
            "constraints_met": int(r.constraints_met), "synthetic_transitions": int(r.num_synthetic_transitions),
            "lookahead_kernel": lookahead_kernels(g, c, params, repeats), "loadavg_before": load0,
            "loadavg_after": os.getloadavg()}
    res["peak_rss_mb"] = peak_rss_mb()
    return res


def markdown(res) -> list:
    lines = ["# Motion graph at scale (sharded construction, graph/stream.py)", "",
             f"Graph overrides: {res.get('graph_overrides') or 'none (the paper rules)'}.", "",
             f"Load average before {res['loadavg_start']}, after {res['loadavg_end']}; {res['machine']}.", "",
             "| frames | wall (s) | CPU (s) | peak RSS (MB) | key states | states after SCC | edges after SCC | shards |",
             "|---|---|---|---|---|---|---|---|"]
    for r in res["builds"]:
        if "error" in r:
            err = r["error"].strip().splitlines()[-1][:300] if r["error"].strip() else "killed"
            lines.append(f"| {r.get('frames', '?')} | failed after {r['wall_s']:.0f} s: {err} | | | | | | |")
            continue
        lines.append(f"| {r['frames']:,} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {r['peak_rss_mb']:.0f} | "
                     f"{r['key_states']:,} | {r['states']:,} | {r['edges']:,} | {r['kernel']['shards']} |")
    if res.get("exponent") is not None:
        lines += ["", f"Fitted exponent (wall ~ frames^b): b = {res['exponent']:.2f}; edges ~ frames^"
                      f"{res['edge_exponent']:.2f}."]
    for s in ([res["search"]] if "search" in res else []) + list(res.get("searches", {}).values()):
        if "characters" not in s:
            continue
        lines += ["", f"Search on the {s['states']:,}-state graph ({s['edges']:,} edges, memory-mapped, loaded in "
                      f"{s['load_s']:.2f} s), first 15 s window of each character, search.lookahead_pass="
                      f"{s.get('lookahead_pass', 'dense')} (warm: median of the warm calls; CPU: process time):", "",
                  "| character | first call (s) | warm (s) | warm CPU (s) | dense look-ahead: warm (s) | warm CPU (s) | "
                  "success | constraints met | same path | without look-ahead (s) |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for k, v in s["characters"].items():
            lines.append(f"| {k} | {v['first_call_s']:.2f} | {v['warm_median_s']:.3f} | {v['warm_cpu_median_s']:.3f} | "
                         f"{v['dense_warm_median_s']:.3f} | {v['dense_warm_cpu_median_s']:.3f} | {v['success_warm']} | "
                         f"{v['constraints_met']}/{v['constraints']} | {v['same_path_as_dense']} | "
                         f"{v['no_lookahead_warm_median_s']:.3f} ({v['no_lookahead_success']}) |")
        lines += ["", "The look-ahead kernel alone (warm medians; frames computed densely / by changed states; "
                      "changed states per frame):", "",
                  "| character | pass | wall (s) | CPU (s) | dense frames | changed-state frames | fixed-point frames | "
                  "changed states p10 / median / p90 / max | bits equal | load before / after |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for k, v in s["characters"].items():
            la = v["lookahead_kernel"]
            for name in ("dense", "changed"):
                x = la[name]
                q = x["changed_states_per_frame"]
                lines.append(f"| {k} | {name} | {x['warm_median_s']:.3f} | {x['warm_cpu_median_s']:.3f} | "
                             f"{x['frames_dense']} | {x['frames_changed']} | {x['frames_fixed_point']} | "
                             f"{q['p10']:.0f} / {q['median']:.0f} / {q['p90']:.0f} / {q['max']:.0f} | {la['bits_equal']} | "
                             f"{v['loadavg_before'][0]:.1f} / {v['loadavg_after'][0]:.1f} |")
    lines += ["", f"Goals: 1M construction <= {GOALS['construction_1m_s']:.0f} s, peak RSS <= {GOALS['peak_rss_mb']:.0f} MB, "
                  f"warm search <= {GOALS['warm_search_s']} s."]
    return lines


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", default="54067,216268,1000000")
    ap.add_argument("--work", default=str(REPO / "data_cache" / "scale"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--name", default="bench_scale")
    ap.add_argument("--skip-search", action="store_true")
    ap.add_argument("--search-only", help="only the search, on the graphs already built for these sizes (comma-separated)")
    ap.add_argument("--graph", default="", help="comma-separated graph overrides for every build, e.g. "
                    "graph.max_out_degree=32")
    ap.add_argument("--make", type=int, help="(child) make the database of this many frames")
    ap.add_argument("--build", type=int, help="(child) build the graph of this database")
    ap.add_argument("--search", type=int, help="(child) search on the graph of this database")
    args = ap.parse_args()
    work = Path(args.work)
    db_dir = lambda n: work / f"db_{n}"  # noqa: E731
    out_dir = lambda n: work / f"build_{n}"  # noqa: E731
    if args.make:
        print(json.dumps(make_db(args.make, db_dir(args.make)), default=float))
        raise SystemExit(0)
    if args.build:
        print(json.dumps(build(db_dir(args.build), out_dir(args.build), [x for x in args.graph.split(",") if x]),
                         default=float))
        raise SystemExit(0)
    if args.search:
        print(json.dumps(search(out_dir(args.search), args.repeats), default=float))
        raise SystemExit(0)
    if args.search_only:
        res = {"loadavg_start": os.getloadavg(), "command": "python experiments/bench/bench_scale.py " + " ".join(sys.argv[1:]),
               "machine": f"{os.cpu_count()} CPU cores, shared with other jobs", "builds": [],
               "searches": {n: child("--search", n, "--work", str(work), "--repeats", str(args.repeats))
                            for n in args.search_only.split(",")}}
        res["loadavg_end"] = os.getloadavg()
        res["goals"] = GOALS
        write_result(args.name, res)
        write_result_markdown(args.name, markdown(res))
        raise SystemExit(0)
    sizes = [int(x) for x in args.frames.split(",")]
    res = {"loadavg_start": os.getloadavg(), "command": "python experiments/bench/bench_scale.py " + " ".join(sys.argv[1:]),
           "machine": f"{os.cpu_count()} CPU cores, shared with other jobs", "graph_overrides": args.graph,
           "databases": [], "builds": []}
    for n in sizes:
        if not (db_dir(n) / "manifest.json").is_file():
            res["databases"].append(child("--make", str(n), "--work", str(work)))
        res["builds"].append(child("--build", str(n), "--work", str(work), "--graph", args.graph))
        print(json.dumps(res["builds"][-1], default=float)[:400], flush=True)
    ok = [r for r in res["builds"] if "error" not in r]
    if len(ok) >= 2:
        x = np.log([r["frames"] for r in ok])
        res["exponent"] = float(np.polyfit(x, np.log([r["wall_s"] for r in ok]), 1)[0])
        res["edge_exponent"] = float(np.polyfit(x, np.log([r["edges"] for r in ok]), 1)[0])
    if ok and not args.skip_search:   # on every graph: the look-ahead's passes compared on each size
        res["searches"] = {str(r["frames"]): child("--search", str(r["frames"]), "--work", str(work), "--repeats",
                                                   str(args.repeats)) for r in ok}
    res["loadavg_end"] = os.getloadavg()
    res["goals"] = GOALS
    write_result(args.name, res)
    write_result_markdown(args.name, markdown(res))
