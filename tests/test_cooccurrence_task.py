"""Table 1 end to end on the tiny synthetic corpus (task ``cooccurrence``): files and columns, rates
against the planted ground truth, significance against chance, negative controls; Figure 6 (task
``user_study``) and the plotting helpers."""
import dataclasses
import json

import matplotlib
import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import FormatError, MissingFileError
from convsynth_jax.stats.cooccurrence import TABLE_COLUMNS, cooccurrence_by_session, cooccurrence_table
from convsynth_jax.stats.params import StatsParams

AP, SP = AnnotateParams(), StatsParams()

HYPS = ["PC-LH", "PC-RH", "PC-LH/RH", "LR-Nod", "PH-Nod"]
# hypothesis -> (audio kind, planted motion kinds, whose audio)
SPEC = {"PC-LH": ("PC", ["LH"], "own"), "PC-RH": ("PC", ["RH"], "own"), "PC-LH/RH": ("PC", ["LH", "RH"], "own"),
        "LR-Nod": ("LR", ["Nod"], "own"), "PH-Nod": ("HP", ["Nod"], "partner")}
ROLES = {"female": "main-agent", "male": "interloctr"}


@pytest.fixture(scope="module")
def task_out(tiny_corpus_dir, tiny_cache_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("cooccurrence")
    cfg = compose(["task=cooccurrence", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}",
                   f"cache_dir={tiny_cache_dir()}", "progress=false"])
    summary = run_task(cfg, out)
    return out, summary


@pytest.fixture(scope="module")
def annotations(tiny_annotations):
    import copy

    return copy.deepcopy(tiny_annotations)   # annotated once per session with AnnotateParams()


def planted_rates(events: pd.DataFrame) -> dict:
    """(character, hypothesis) -> share of audio segments that caused at least one planted movement of
    the hypothesis' kind (from the generator's ground truth, independent of any detection)."""
    out = {}
    for char, role in ROLES.items():
        for h, (akind, kinds, whose) in SPEC.items():
            who = (events.participant == role) if whose == "own" else (events.participant != role)
            audio = events[(events.kind == akind) & who]
            caused = events[(events.participant == role) & (events.source == akind) & events.kind.isin(kinds)]
            out[(char, h)] = caused.groupby(["session", "cause_start"]).ngroups / len(audio)
    return out


def test_task_writes_table_1(task_out):
    out, summary = task_out
    t = pd.read_csv(out / "cooccurrence.csv")
    assert list(t.columns) == TABLE_COLUMNS
    assert t["character"].tolist() == ["female"] * 5 + ["male"] * 5
    assert t["hypothesis"].tolist() == HYPS * 2
    np.testing.assert_allclose(t["rate"], t["matched"] / t["total"])
    np.testing.assert_allclose(t["chance_rate"], t["chance_matched"] / t["chance_total"])
    assert (t["df"] == 1).all() and t["p_chi2"].between(0, 1).all() and t["p_permutation"].between(0, 1).all()
    # LH/RH counts a clause once even when both hands move
    for c in ("female", "male"):
        g = t[t.character == c].set_index("hypothesis")
        assert max(g.loc["PC-LH", "matched"], g.loc["PC-RH", "matched"]) <= g.loc["PC-LH/RH", "matched"] \
            <= g.loc["PC-LH", "matched"] + g.loc["PC-RH", "matched"]
    md = (out / "cooccurrence.md").read_text()
    assert "| character | hypothesis |" in md and "PC-LH/RH" in md
    assert "tabular" in (out / "cooccurrence.tex").read_text()
    assert (out / "cooccurrence.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ev = pd.read_csv(out / "events.csv")
    assert {"kind", "start", "peak", "end", "channel", "segment", "session", "role", "character"} <= set(ev.columns)
    assert set(ev["kind"]) == {"LH", "RH", "Nod"} and (ev["start"] <= ev["peak"]).all() and (ev["peak"] < ev["end"]).all()
    s = json.loads((out / "summary.json").read_text())
    assert s["task"] == "cooccurrence" and len(s["rows"]) == 10 and s == json.loads(json.dumps(summary, default=str))


def test_per_session_breakdown_adds_up(task_out):
    out, _ = task_out
    t = pd.read_csv(out / "cooccurrence.csv")
    b = pd.read_csv(out / "cooccurrence_by_session.csv")
    assert list(b.columns) == ["session"] + TABLE_COLUMNS and b["session"].nunique() == 3
    sums = b.groupby(["character", "hypothesis"])[["matched", "total", "chance_matched", "chance_total"]].sum()
    merged = t.set_index(["character", "hypothesis"])[sums.columns].join(sums, rsuffix="_s")
    for c in sums.columns:
        assert (merged[c] == merged[f"{c}_s"]).all(), c


def test_rates_match_planted_and_beat_chance(task_out, tiny_corpus_dir):
    """Detection error only: the planted rates are the realised ones of this very corpus, so no
    sampling error enters. Tolerance: 5 percentage points or one segment, whichever is larger
    (a tiny corpus has 9-40 segments per row). Significance levels follow the power the tiny corpus
    has (random windows also catch the generator's spontaneous movements): PC rows (37 clauses)
    p < 0.01, LR rows (16-17 responses) p < 0.05; PH-Nod has 9 hesitations per character here and
    must only beat chance in rate (experiments/analysis/eval_annotation.py tests every row on the default
    corpus)."""
    out, _ = task_out
    t = pd.read_csv(out / "cooccurrence.csv")
    planted = planted_rates(pd.read_csv(tiny_corpus_dir / "events.csv"))
    for r in t.itertuples():
        tol = max(0.05, 1.0 / r.total) + 1e-9
        assert abs(r.rate - planted[(r.character, r.hypothesis)]) <= tol, (r.character, r.hypothesis, r.rate)
        assert r.rate > r.chance_rate
        level = {"LR-Nod": 0.05, "PH-Nod": 1.0}.get(r.hypothesis, 0.01)
        assert r.p_chi2 <= level and r.p_permutation <= level, (r.character, r.hypothesis)


def _control(annotations, how: str) -> list:
    names = list(annotations)
    out = []
    for i, s in enumerate(names):
        for role, a in annotations[s].items():
            if how == "swap":  # audio of one session, motion of the next one
                m = annotations[names[(i + 1) % len(names)]][role].motion
                m = m.slice(0, min(m.num_frames, a.motion.num_frames))
            else:  # the same motion, circularly shifted by a third of the clip
                k = a.motion.num_frames // 3
                m = dataclasses.replace(a.motion, rotations=np.roll(a.motion.rotations, k, 0),
                                        translations=np.roll(a.motion.translations, k, 0))
            out.append(dataclasses.replace(a, motion=m))
    return out


@pytest.mark.parametrize("how", ["swap", "shift"])
def test_negative_controls_show_no_cooccurrence(annotations, how):
    real = cooccurrence_table(annotations, AP, SP)
    ctrl = cooccurrence_table(_control(annotations, how), AP, SP)
    assert (ctrl["total"] == real["total"]).all()
    # nothing ABOVE chance: the one-sided permutation test stays quiet, and the two-sided chi-square
    # may only flag a rate below chance (random windows can land where the unrelated motion moves)
    assert (ctrl["p_permutation"] > 0.01).all(), ctrl
    assert not ((ctrl["rate"] > ctrl["chance_rate"]) & (ctrl["p_chi2"] < 0.01)).any(), ctrl
    pc = ctrl["hypothesis"].str.startswith("PC")
    assert (ctrl.loc[pc, "rate"] < real.loc[pc, "rate"]).all()


def test_table_is_deterministic_and_seeded(annotations):
    a = cooccurrence_table(annotations, AP, SP, seed=0)
    b = cooccurrence_table(annotations, AP, SP, seed=0)
    c = cooccurrence_table(annotations, AP, SP, seed=1)
    pd.testing.assert_frame_equal(a, b)
    assert (a[["matched", "total"]] == c[["matched", "total"]]).all().all()  # the audio side has no randomness
    assert not a["chance_matched"].equals(c["chance_matched"]) or not a["p_permutation"].equals(c["p_permutation"])
    by = cooccurrence_by_session(annotations, AP, SP)
    assert by["session"].nunique() == len(annotations)
    more = cooccurrence_table(annotations, AP, StatsParams(chance_windows=3))
    assert (more["chance_total"] >= 2 * a["chance_total"]).all()


# ------------------------------------------------------------------------------------ Figure 6
def test_user_study_task_paper_counts(tmp_path):
    s = run_task(compose(["task=user_study"]), tmp_path)
    t = pd.read_csv(tmp_path / "user_study.csv")
    assert [f"{x:.4g}" for x in t["chi2"]] == ["57.56", "5.016", "1.433", "9.61"]
    assert t["significant"].tolist() == [True, True, False, True]  # the paper's stars (p < 0.03)
    assert t["preferred_b"].tolist() == [64, 85, 107, 84]
    assert (tmp_path / "figure6.png").read_bytes()[:4] == b"\x89PNG" and (tmp_path / "user_study.md").is_file()
    assert len(s["rows"]) == 4


def test_user_study_task_own_csv_and_bad_input(tmp_path):
    good = tmp_path / "answers.csv"
    good.write_text("comparison,preferred_a,total\nours vs theirs,30,40\n")
    s = run_task(compose(["task=user_study", f"task.csv={good}"]), tmp_path / "out")
    assert s["rows"][0]["p_value"] < 0.01 and s["rows"][0]["share_a"] == 0.75
    for body, match in [("comparison,total\nx,3\n", "needs columns"),
                        ("comparison,preferred_a,total\nx,5,4\n", "line 2"),
                        ("comparison,preferred_a,total\nx,1,4\ny,two,4\n", "line 3")]:
        bad = tmp_path / "bad.csv"
        bad.write_text(body)
        with pytest.raises(FormatError, match=match) as e:
            run_task(compose(["task=user_study", f"task.csv={bad}"]), tmp_path / "bad")
        assert str(bad) in str(e.value)
    with pytest.raises(MissingFileError):
        run_task(compose(["task=user_study", f"task.csv={tmp_path / 'nope.csv'}"]), tmp_path / "none")


def test_plotting_helpers_draw_the_data():
    from convsynth_jax.figures.motion_graph import figure6_figure, table1_figure
    from convsynth_jax.tasks.user_study import analyse

    t = analyse(pd.DataFrame({"comparison": ["A vs B", "C vs D"], "preferred_a": [70, 40], "total": [100, 100]}))
    fig = figure6_figure(t)
    assert isinstance(fig, matplotlib.figure.Figure)
    widths = sorted(round(p.get_width(), 6) for p in fig.axes[0].patches)
    assert widths == [30.0, 40.0, 60.0, 70.0]  # stacked: share of A and of B per comparison
    table = pd.DataFrame({"character": ["f", "f"], "hypothesis": ["PC-LH", "LR-Nod"], "rate": [0.5, 0.25],
                          "chance_rate": [0.1, 0.0]})
    heights = sorted(round(p.get_height(), 6) for p in table1_figure(table).axes[0].patches)
    assert heights == [0.0, 10.0, 25.0, 50.0]
