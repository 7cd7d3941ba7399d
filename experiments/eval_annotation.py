"""Evidence for the annotation pipeline on the synthetic default corpus: detected motion events vs
the planted ground truth (precision, recall), measured co-occurrence rates vs the planted rates
(events.csv) and the configured probabilities, and significance against chance.
Writes experiments/results/eval_annotation.json and .md.

    python experiments/eval_annotation.py [--cache DIR]
"""
import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from _bench import REPO, RESULTS, write

from convsynth_jax.config import compose
from convsynth_jax.data import resolve_config
from convsynth_jax.evaluation.loo import annotate_corpus_cached
from convsynth_jax.evaluation.summaries import to_markdown
from convsynth_jax.stats.cooccurrence import cooccurrence_table
from convsynth_jax.tasks.common import open_corpus


def overlap_counts(planted, detected):
    hp = sum(((detected["start"] < r.end) & (detected["end"] > r.start)).any() for r in planted.itertuples())
    hd = sum(((planted["start"] < r.end) & (planted["end"] > r.start)).any() for r in detected.itertuples())
    return hp, len(planted), hd, len(detected)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    args = ap.parse_args()
    cfg = compose([f"cache_dir={args.cache}", "progress=false"])
    corpus = open_corpus(cfg)
    ann = annotate_corpus_cached(corpus, cfg, Path(args.cache) / "loo_cache")
    ev = pd.read_csv(Path(corpus.root) / "events.csv")
    pr = np.zeros(4)
    per_kind = {}
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = ev[(ev.session == s) & (ev.participant == role) & (ev.source != "spontaneous")]
            for k in ("LH", "RH", "Nod"):
                c = np.array(overlap_counts(pl[pl.kind == k], a.events[a.events.kind == k]))
                pr += c
                per_kind[k] = per_kind.get(k, np.zeros(4)) + c
    table = cooccurrence_table([a for p in ann.values() for a in p.values()], cfg)
    gen = resolve_config(corpus.metadata.get("config"))
    roles = {v["name"]: r for r, v in gen["characters"].items()}
    key = {"PC-LH": "p_pc_lh", "PC-RH": "p_pc_rh", "PC-LH/RH": "p_pc_either", "LR-Nod": "p_lr_nod", "PH-Nod": "p_ph_nod"}
    rows = []
    for r in table.itertuples():
        role = roles[r.character]
        own = ev[ev.participant == role]
        cause = own[own.source.isin(["PC", "LR", "HP"])]
        src, kinds = {"PC-LH": ("PC", ["LH"]), "PC-RH": ("PC", ["RH"]), "PC-LH/RH": ("PC", ["LH", "RH"]),
                      "LR-Nod": ("LR", ["Nod"]), "PH-Nod": ("HP", ["Nod"])}[r.hypothesis]
        audio = ev[(ev.kind == src) & ((ev.participant == role) if src != "HP" else (ev.participant != role))]
        planted = cause[(cause.source == src) & cause.kind.isin(kinds)].groupby(["session", "cause_start"]).ngroups
        rows.append({"character": r.character, "hypothesis": r.hypothesis, "measured_rate": r.rate,
                     "planted_rate": planted / max(1, len(audio)), "configured": gen["characters"][role][key[r.hypothesis]],
                     "chance_rate": r.chance_rate, "p_chi2": r.p_chi2, "p_permutation": r.p_permutation})
    comp = pd.DataFrame(rows)
    comp["measured_minus_planted_pp"] = 100 * (comp["measured_rate"] - comp["planted_rate"])
    res = {"precision": pr[2] / pr[3], "recall": pr[0] / pr[1],
           "per_kind": {k: {"recall": v[0] / v[1], "precision": v[2] / v[3]} for k, v in per_kind.items()},
           "max_abs_rate_error_pp": float(comp["measured_minus_planted_pp"].abs().max()),
           "all_rows_significant_p_lt_0.01": bool((comp["p_chi2"] < 0.01).all() and (comp["p_permutation"] < 0.01).all()),
           "rows": comp.to_dict(orient="records")}
    (RESULTS / "eval_annotation.md").parent.mkdir(parents=True, exist_ok=True)
    (RESULTS / "eval_annotation.md").write_text(to_markdown(comp))
    write("eval_annotation", res)
