"""task=collect on every kind of sweep: a converse multirun over conditions (each job's results read,
constraints met counted on condition all's constraints), benchmark, Walk the Talk and CDBN jobs,
failed jobs, and the summary tables' vocabulary (windows vs character-windows)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from convsynth_jax.config import compose, run_task
from convsynth_jax.evaluation import summaries
from convsynth_jax.evaluation.collect import collect_sweep

REPO = Path(__file__).resolve().parent.parent
SECONDS = 12.0
CONDITIONS = ("all", "no_lr", "none")


def _job(sweep: Path, num: int, overrides: list[str], cfg=None) -> Path:
    """A job folder as Hydra's multirun writes it (``<sweep>/<num>/.hydra/overrides.yaml``, config.yaml)."""
    from omegaconf import OmegaConf

    job = sweep / str(num)
    (job / ".hydra").mkdir(parents=True)
    (job / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
    if cfg is not None:
        OmegaConf.save(cfg, job / ".hydra" / "config.yaml")
    return job


@pytest.fixture(scope="module")
def converse_sweep(tiny_corpus_dir, tiny_cache_dir, tmp_path_factory) -> Path:
    """``convsynth -m task=converse task.condition=all,no_lr,none`` on SECONDS of the tiny corpus's
    session01 (one window), laid out as Hydra's multirun lays it out."""
    from convsynth_jax.io import load_audio, load_transcript, save_wav
    from convsynth_jax.io.transcripts import save_transcript_tsv

    d = tmp_path_factory.mktemp("collect_converse_in")
    inputs = []
    for role, x in (("main-agent", "a"), ("interloctr", "b")):
        a = load_audio(tiny_corpus_dir / f"session01_{role}.wav")
        save_wav(d / f"{x}.wav", a.samples[:int(SECONDS * a.sample_rate)], a.sample_rate)
        w = load_transcript(tiny_corpus_dir / f"session01_{role}.tsv")
        save_transcript_tsv(w[w["end"] <= SECONDS].reset_index(drop=True), d / f"{x}.tsv")
        inputs += [f"task.audio_{x}={d / f'{x}.wav'}", f"task.transcript_{x}={d / f'{x}.tsv'}"]
    cache = tiny_cache_dir("collect_cache")
    sweep = tmp_path_factory.mktemp("multirun_converse")
    for n, cond in enumerate(CONDITIONS):
        over = ["task=converse", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                "progress=false", "task.video=false", *inputs, f"task.condition={cond}"]
        cfg = compose(over)
        job = _job(sweep, n, over, cfg)
        assert run_task(cfg, job)["success"]
    return sweep


def test_collect_reads_a_converse_multirun_over_conditions(converse_sweep, tmp_path, capsys):
    """Regression: collect used to look for cases.csv in every job, so a converse sweep whose jobs all
    succeeded came out as every job failed (``job wrote no cases.csv``) with empty tables."""
    s = run_task(compose(["task=collect", f"task.dir={converse_sweep}"]), tmp_path)
    assert s["num_failed_jobs"] == 0 and s["num_jobs"] == 3 and s["kinds"] == ["converse"]
    assert s["axes"] == ["task.condition"] and s["main_table"] == "converse_by_condition"
    table = pd.read_csv(tmp_path / "converse_by_condition.csv")
    assert sorted(zip(table["condition"], table["speaker"])) == sorted((c, w) for c in CONDITIONS for w in "AB")
    # the main table is printed
    assert "converse_by_condition" in capsys.readouterr().out
    for who, g in table.groupby("speaker"):
        g = g.set_index("condition")
        # one denominator per speaker in every condition: condition all's constraints
        assert g["constraints"].nunique() == 1 and (g["reference"] == "all").all()
        assert g.loc["all", "constraints"] == g.loc["all", "checked"] and g.loc["all", "switched_off"] == 0
        # under none the partner-hesitation and listener-response constraints are switched off and reported apart
        assert set(g.loc["none", "kinds_off"].split(",")) == {"LR", "PH"}
        assert (g["on"] + g["switched_off"] == g["constraints"]).all()
        assert (g["met"] <= g["on"]).all() and (g["not_checked"] == 0).all()
        assert g.loc["none", "on"] == g.loc["none", "checked"]  # what the condition checked, all of it in all's set
        report = json.loads((converse_sweep / "0" / "report.json").read_text())["characters"][who]
        assert g.loc["all", "met"] == report["checker"]["total"]["met"]
    kinds = pd.read_csv(tmp_path / "converse_by_kind.csv")
    assert not kinds.loc[(kinds["condition"] == "none") & (kinds["kind"] == "PH"), "on"].any()
    assert (tmp_path / "converse_by_condition.png").is_file() and (tmp_path / "converse_by_condition.md").is_file()


def test_converse_shares_on_the_reference_denominator():
    """Hand-made: under no_lr the LR constraint is switched off (reported apart, not met), a PC the
    condition did not check counts as not checked, and both conditions share all's denominator."""
    key = lambda kind, s: {"kind": kind, "start": s, "end": s + 10}
    cons = pd.DataFrame([
        {"job_dir": "0", "condition": "all", "speaker": "A", **key("PC", 0), "met": True},
        {"job_dir": "0", "condition": "all", "speaker": "A", **key("PC", 20), "met": True},
        {"job_dir": "0", "condition": "all", "speaker": "A", **key("LR", 40), "met": False},
        {"job_dir": "0", "condition": "all", "speaker": "A", **key("idle", 60), "met": True},
        {"job_dir": "1", "condition": "no_lr", "speaker": "A", **key("PC", 0), "met": True},
        {"job_dir": "1", "condition": "no_lr", "speaker": "A", **key("idle", 60), "met": False},
        {"job_dir": "1", "condition": "no_lr", "speaker": "A", **key("idle", 70), "met": True},   # not in all's set
    ])
    spk = pd.DataFrame([{"job_dir": "0", "condition": "all", "speaker": "A", "character": "f", "kinds_off": ""},
                        {"job_dir": "1", "condition": "no_lr", "speaker": "A", "character": "f", "kinds_off": "LR"}])
    t = summaries.converse_constraints_met(cons, spk).set_index("condition")
    assert t.loc["all", ["constraints", "met", "switched_off", "on", "not_checked"]].tolist() == [4, 3, 0, 4, 0]
    assert t.loc["no_lr", ["constraints", "met", "switched_off", "on", "not_checked", "checked"]].tolist() == [4, 1, 1, 3, 1, 3]
    assert t.loc["no_lr", "share_met"] == pytest.approx(1 / 4) and t.loc["no_lr", "share_met_on"] == pytest.approx(1 / 3)
    by_kind = summaries.converse_constraints_by_kind(cons, spk).set_index(["condition", "kind"])
    assert not by_kind.loc[("no_lr", "LR"), "on"] and by_kind.loc[("no_lr", "LR"), "constraints"] == 1
    assert by_kind.loc[("no_lr", "LR"), "met"] == 0


def test_collect_benchmark_walktalk_cdbn_and_failed_jobs(tmp_path):
    """Each kind of job is read by the task its summary names; the override that differs between jobs
    becomes a column; a job that failed, or wrote nothing, is counted and kept with its error."""
    sweep = tmp_path / "multirun"
    board = pd.read_csv(REPO / "experiments" / "results" / "bench_metrics_leaderboard.csv")
    board = board[board["metric"].isin(["jerk", "fgd_raw", "beat_consistency"])]
    for n, folds in enumerate(("[0]", "[1]")):
        job = _job(sweep, n, [f"task.folds={folds}"])
        board.assign(value=board["value"] + n).to_csv(job / "leaderboard.csv", index=False)
        (job / "summary.json").write_text(json.dumps({"task": "benchmark", "success": True}))
    job = _job(sweep, 2, ["task.folds=[2]"])
    (job / "summary.json").write_text(json.dumps({"task": "benchmark", "success": False, "error": "no windows"}))
    _job(sweep, 3, ["task.folds=[3]"])   # killed before writing anything
    s = run_task(compose(["task=collect", f"task.dir={sweep}"]), tmp_path / "col")
    assert s["num_failed_jobs"] == 2 and s["kinds"] == ["benchmark"] and s["main_table"] == "leaderboard_wide"
    jobs = pd.read_csv(tmp_path / "col" / "jobs.csv").set_index("job_dir")
    assert jobs.loc[2, "error"] == "no windows" and jobs.loc[3, "status"] == "error"
    wide = pd.read_csv(tmp_path / "col" / "leaderboard_wide.csv")
    assert sorted(wide["folds"].unique()) == ["[0]", "[1]"] and "jerk" in wide and (tmp_path / "col" / "leaderboard.png").is_file()

    # Walk the Talk: the stored presets sweep (one folder per preset, no Hydra record: read by its files)
    wt = collect_sweep(REPO / "experiments" / "results" / "walktalk_eval_presets")
    assert wt.kinds == ["walktalk"] and wt.num_failed == 0
    assert set(wt.tables["walktalk"]["job_dir"]) == {"paper", "quality"}

    # CDBN: jobs of task=cdbn_eval over a setting
    cdbn = tmp_path / "cdbn"
    for n, k in enumerate((8, 16)):
        job = _job(cdbn, n, [f"cdbn.eval.states={k}"])
        pd.DataFrame({"model": ["jdbn", "cdbn"], "kld": [2.0 + n, 1.0 + n]}).to_csv(job / "table_head.csv", index=False)
        (job / "summary.json").write_text(json.dumps({"task": "cdbn_eval", "success": True}))
    s = run_task(compose(["task=collect", f"task.dir={cdbn}"]), tmp_path / "col_cdbn")
    head = pd.read_csv(tmp_path / "col_cdbn" / "cdbn_head.csv")
    assert s["main_table"] == "cdbn_head" and sorted(head["states"]) == [8, 8, 16, 16] and s["num_failed_jobs"] == 0


def test_success_tables_say_windows_and_character_windows():
    """A window (test case) is solved when every character is; the per-character table counts character-windows."""
    cases = pd.DataFrame({"fold": 0, "session": "s", "condition": ["all"] * 4, "window": [0, 0, 1, 1],
                          "character": ["f", "m", "f", "m"], "success": [True, False, True, True]})
    r = summaries.success_rates(cases).iloc[0]
    assert (r["windows"], r["solved_windows"], r["success_rate"]) == (2, 1, 0.5)
    c = summaries.success_by_character(cases).set_index("character")
    assert c.loc["m", ["character_windows", "solved_character_windows"]].tolist() == [2, 1]


def test_collect_walktalk_copy_is_not_mistaken_for_a_failed_job(tmp_path):
    """A job folder without a Hydra record but with a kind's file is read (not counted failed)."""
    src = REPO / "experiments" / "results" / "walktalk_eval_presets" / "paper"
    shutil.copytree(src, tmp_path / "one")
    sw = collect_sweep(tmp_path / "one")
    assert sw.num_failed == 0 and list(sw.jobs["job_dir"]) == ["."]


def test_table2_small_scc_at_another_k_is_information_not_a_warning(caplog):
    """The main job builds Table 2's graphs at k = 2..4; a small SCC at k = 2 is expected there and
    used to be logged as a warning ("raise graph.quantile or graph.k"). At the configured k it still warns."""
    import logging

    from convsynth_jax.graph.build import scc_warning
    from convsynth_jax.tasks.main import expected_scc_warnings

    log = logging.getLogger("convsynth_jax.graph.build")
    with caplog.at_level(logging.INFO, logger="convsynth_jax.graph.build"), expected_scc_warnings(3):
        log.warning("%s", scc_warning(100, 1000, 50, 2))
        log.warning("%s", scc_warning(100, 1000, 50, 3))
    log.warning("%s", scc_warning(100, 1000, 50, 2))   # outside the main job's Table 2: a warning
    levels = [(r.levelname, "k = 2" in r.getMessage()) for r in caplog.records if "strongly connected" in r.getMessage()]
    assert levels == [("INFO", True), ("WARNING", False), ("WARNING", True)]


def test_paper_task_regenerates_the_reports_artifacts_from_files(main_run, tmp_path):
    """task=paper redraws every paper table and figure of the main report from the run's files alone
    (the same sections, the same numbers) and, with task.sweep, takes the leave-one-out artifacts from a
    collected sweep (here the stored 17-fold one)."""
    out, _ = main_run
    s = run_task(compose(["task=paper", f"path={out}"]), tmp_path / "a")
    section = lambda text: text[text.index("## Table 1"):text.index("## Motion quality")]
    assert section((tmp_path / "a" / "report.md").read_text()) == section((out / "report.md").read_text())
    for f in ("table1_beside_paper.png", "figure4.png", "success_beside_paper.png", "figure6.png", "table2.csv"):
        assert f in s["files"], f
    sweep = REPO / "experiments" / "results" / "loo_default"
    s = run_task(compose(["task=paper", f"path={out}", f"task.sweep={sweep}"]), tmp_path / "b")
    rates = pd.read_csv(tmp_path / "b" / "success_beside_paper.csv").set_index("condition")
    stored = pd.read_csv(sweep / "success_rates.csv").set_index("condition")
    assert rates.loc["all", "windows"] == stored.loc["all", stored.columns.intersection(["windows", "cases"])[0]]
    assert "paper_success_rate" in rates
