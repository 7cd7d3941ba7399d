"""Task ``main`` (``convsynth`` with no arguments): the whole pipeline on the configured corpus.

1. generate (or reuse) the synthetic default corpus and annotate it;
2. Table 1: audio-motion co-occurrence with tests against chance (printed and written);
3. fit the configured system (``system=``, default the motion graphs) without the held-out session
   (``task.fold``);
4. leave-one-out on that session in every condition of the system (``task.conditions``, default all
   of them), exporting BVH;
5. a Markdown report (``report.md``) with the tables and figures.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from ..evaluation import summaries
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)


def _csv(df: pd.DataFrame, path: Path) -> None:
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def run(cfg, out_dir: Path) -> dict:
    from ..errors import ConfigError
    from ..evaluation.loo import fit_fold, run_fold
    from ..figures import ablation_figure, success_rate_figure
    from ..stats.cooccurrence import cooccurrence_table
    from .common import annotated_corpus, cache_dir, make_configured_system, open_corpus, params_of

    t_start = time.perf_counter()
    timings = {}
    params = params_of(cfg)
    system = make_configured_system(params)
    conditions = list(cfg.task.get("conditions") or system.conditions)
    for cond in conditions:  # unknown conditions fail before any work
        system.condition_options(cond)
    progress = params.progress
    steps = tqdm(total=5, desc="convsynth main", disable=not progress)

    t0 = time.perf_counter()
    corpus = open_corpus(params)
    if len(corpus.sessions) < 2:
        raise ConfigError(f"the main job runs leave-one-out, which needs at least two sessions; {corpus.root} has "
                          f"{len(corpus.sessions)} (use task=cooccurrence for Table 1 alone)")
    cache = cache_dir(params)
    _, annotations = annotated_corpus(params)
    timings["corpus_and_annotation_s"] = time.perf_counter() - t0
    steps.update()

    t0 = time.perf_counter()
    table1 = cooccurrence_table(list(_participants(annotations)), params.annotate, params.stats, params.seed)
    _csv(table1, out_dir / "table1_cooccurrence.csv")
    md1 = summaries.to_markdown(table1)
    write_text_atomic(out_dir / "table1_cooccurrence.md", md1)
    print("\nTable 1: audio-motion co-occurrence\n" + md1)
    timings["table1_s"] = time.perf_counter() - t0
    steps.update()

    fold = int(cfg.task.get("fold", 0))
    held_out = corpus.sessions[fold].name
    t0 = time.perf_counter()
    models: dict = {}
    fitted = fit_fold(system, annotations, held_out, conditions[0], cache, models)
    model_rows = []
    for c, m in fitted.items():
        row = {"character": c, "fit_s": system.fit_seconds(m)}
        g = getattr(m, "graph", None)
        if g is not None:  # a motion graph: its size and threshold, and the graph file
            row.update({"num_states": g.num_states, "num_edges": g.num_edges, "threshold": g.meta.get("threshold")})
            g.save(out_dir / f"graph_{c}.npz")
        model_rows.append(row)
    graphs = pd.DataFrame(model_rows)
    _csv(graphs, out_dir / "graphs.csv")
    print("Fitted %s models (held-out session %s)\n%s" % (system.name, held_out, summaries.to_markdown(graphs)))
    timings["fit_s"] = time.perf_counter() - t0
    steps.update()

    t0 = time.perf_counter()
    frames = []
    for cond in tqdm(conditions, desc="leave-one-out conditions", disable=not progress, leave=False):
        frames.append(run_fold(system, annotations, fold, cond, params, out_dir=out_dir, cache_dir=cache,
                               export_bvh=bool(cfg.task.get("export_bvh", True)), models=models,
                               with_audio=system.needs_audio))
    cases = pd.concat(frames, ignore_index=True)
    _csv(cases, out_dir / "cases.csv")
    timings["leave_one_out_s"] = time.perf_counter() - t0
    steps.update()

    rates = summaries.success_rates(cases)
    co = summaries.cooccurrence_by_condition(cases)
    quality = summaries.quality_by_condition(cases)
    timing = summaries.timing_table(cases)
    for name, df in (("success_rates", rates), ("cooccurrence_by_condition", co),
                     ("quality_by_condition", quality), ("table3", timing)):
        _csv(df, out_dir / f"{name}.csv")
    fig = success_rate_figure(rates)
    fig.savefig(out_dir / "success_rates.png", dpi=120)
    if not co.empty:
        ablation_figure(co).savefig(out_dir / "ablation.png", dpi=120)
    report = [
        "# convsynth main report", "",
        f"Corpus: `{corpus.root}` ({len(corpus.sessions)} sessions). Held-out session: `{held_out}` (fold {fold}).", "",
        "## Table 1: audio-motion co-occurrence (whole corpus)", "", md1,
        f"## {system.name} models (fitted without the held-out session)", "", summaries.to_markdown(graphs),
        "## Leave-one-out success rate per condition", "", summaries.to_markdown(rates),
        "![success rates](success_rates.png)", "",
        "## Co-occurrence in synthesized motion vs held-out ground truth", "", summaries.to_markdown(co),
        "![ablation](ablation.png)" if not co.empty else "", "",
        "## Motion quality (means over solved windows)", "", summaries.to_markdown(quality),
        "## Timing (Table 3 style)", "", summaries.to_markdown(timing),
        "## Wall-clock per step", "", summaries.to_markdown(pd.DataFrame([timings])),
        f"Synthesized BVH files: `bvh/` ({len(list((out_dir / 'bvh').glob('*.bvh'))) if (out_dir / 'bvh').exists() else 0} files).",
    ]
    write_text_atomic(out_dir / "report.md", "\n".join(report) + "\n")
    steps.update()
    steps.close()
    print("Success rates\n" + summaries.to_markdown(rates))
    log.info("report: %s", out_dir / "report.md")
    return {"success": True, "system": system.name, "corpus_root": str(corpus.root), "held_out_session": held_out,
            "num_cases": int(len(cases)),
            "success_rates": rates.to_dict(orient="records"), "timings": timings,
            "seconds": time.perf_counter() - t_start}


def _participants(annotations: dict):
    for sess in annotations.values():
        yield from sess.values()
