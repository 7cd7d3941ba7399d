"""Task ``cooccurrence``: Table 1 (audio-motion co-occurrence with tests against chance).

Writes ``cooccurrence.csv`` (``stats.cooccurrence.TABLE_COLUMNS``: character, hypothesis, matched,
total, rate with its Wilson interval ci_low/ci_high, chance_method (away | shifted | none), chance
counts, rate and interval, chi2, df, p_chi2, p_permutation), ``cooccurrence.md``, ``cooccurrence.tex``,
``cooccurrence_by_session.csv``, ``events.csv`` (detected motion events), ``segments.csv`` (audio
segments) and ``cooccurrence.png``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..evaluation.summaries import to_latex, to_markdown
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)


def _csv(df, path):
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


@dataclass(frozen=True)
class CooccurrenceSettings:
    """``conf/task/cooccurrence.yaml``."""

    name: str = "cooccurrence"


def run(cfg, out_dir: Path) -> dict:
    from ..figures import save_figure
    from ..figures.motion_graph import table1_figure
    from ..stats.cooccurrence import TABLE_COLUMNS, cooccurrence_by_session, cooccurrence_table
    from .common import annotated_corpus, pairing_note, params_of

    params = params_of(cfg)
    corpus, ann = annotated_corpus(params)
    parts = [a for s in ann.values() for a in s.values()]
    table = cooccurrence_table(parts, params.annotate, params.stats, params.seed)
    by_session = cooccurrence_by_session(parts, params.annotate, params.stats, params.seed)
    _csv(table, out_dir / "cooccurrence.csv")
    _csv(by_session, out_dir / "cooccurrence_by_session.csv")
    note = pairing_note(corpus)
    write_text_atomic(out_dir / "cooccurrence.md", (f"> NULL CONTROL: {note['pairing_note']}\n\n" if note else "")
                      + to_markdown(table))
    write_text_atomic(out_dir / "cooccurrence.tex", to_latex(table))
    ev = pd.concat([a.events.assign(session=a.session, role=a.role, character=a.character) for a in parts],
                   ignore_index=True)
    seg = pd.concat([a.segments.assign(session=a.session, role=a.role, character=a.character) for a in parts],
                    ignore_index=True)
    _csv(ev, out_dir / "events.csv")
    _csv(seg, out_dir / "segments.csv")
    save_figure(table1_figure(table), out_dir / "cooccurrence.png", dpi=120)
    log.info("%s", "\n" + to_markdown(table))
    return {"corpus_root": str(corpus.root), **note, "columns": TABLE_COLUMNS,
            "num_participants": len(parts), "num_events": int(len(ev)),
            "all_significant_p_lt_0.01": bool(((table["p_chi2"] < 0.01) & (table["p_permutation"] < 0.01)).all()),
            "rows": table.to_dict(orient="records")}
