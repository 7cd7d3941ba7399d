"""Every Hydra task end to end on the tiny synthetic corpus (in-process, via compose + run_task)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import compose, run_task

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def cache(tiny_cache_dir):
    return tiny_cache_dir()


def cfg_for(task, tiny_corpus_dir, cache, *extra):
    return compose([f"task={task}", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                    "progress=false", *extra])


def independent_bvh_positions(path: Path) -> np.ndarray:
    """A separate, minimal BVH reader + FK (scipy Euler, matrices), sharing no code with the project."""
    from scipy.spatial.transform import Rotation

    lines = path.read_text().split("\n")
    names, parents, offsets, chans, stack = [], [], [], [], []
    i = 0
    while not lines[i].strip().startswith("MOTION"):
        tok = lines[i].split()
        if tok and tok[0] in ("ROOT", "JOINT"):
            names.append(tok[1]); parents.append(stack[-1] if stack else -1); offsets.append(None); chans.append([])
            stack.append(len(names) - 1)
        elif tok and tok[0] == "End":
            stack.append(-2)
        elif tok and tok[0] == "OFFSET" and stack[-1] >= 0:
            offsets[stack[-1]] = np.array(tok[1:4], float)
        elif tok and tok[0] == "CHANNELS":
            chans[stack[-1]] = tok[2:]
        elif tok and tok[0] == "}":
            stack.pop()
        i += 1
    data = np.array([[float(x) for x in l.split()] for l in lines[i + 3:] if l.strip()])
    out = np.zeros((len(data), len(names), 3))
    for f, row in enumerate(data):
        col, mats = 0, {}
        for j, ch in enumerate(chans):
            vals = dict(zip(ch, row[col:col + len(ch)])); col += len(ch)
            order = "".join(c[0] for c in ch if c.endswith("rotation"))
            rot = Rotation.from_euler(order, [vals[c + "rotation"] for c in order], degrees=True).as_matrix()
            local_t = np.array([vals["Xposition"], vals["Yposition"], vals["Zposition"]]) if "Xposition" in vals else offsets[j]
            if parents[j] < 0:
                mats[j], out[f, j] = rot, local_t
            else:
                mats[j] = mats[parents[j]] @ rot
                out[f, j] = out[f, parents[j]] + mats[parents[j]] @ local_t
    return out


def test_make_corpus_task(tmp_path):
    s = run_task(compose(["task=make_corpus", "corpus=synthetic_tiny", "corpus.generator.num_sessions=1",
                          "corpus.generator.session_seconds=15", f"cache_dir={tmp_path}"]), tmp_path / "out")
    assert s["num_sessions"] == 1 and (Path(s["corpus_root"]) / "events.csv").is_file()
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["task"] == "make_corpus"


def test_cooccurrence_and_user_study_tasks(tiny_corpus_dir, cache, tmp_path):
    run_task(cfg_for("cooccurrence", tiny_corpus_dir, cache), tmp_path)
    t = pd.read_csv(tmp_path / "cooccurrence.csv")
    assert {"character", "hypothesis", "matched", "total", "rate", "chi2", "df", "p_chi2", "p_permutation"} <= set(t.columns)
    assert set(t["character"]) == {"female", "male"} and len(t) == 10
    assert t["rate"].between(0, 1).all()
    for f in ("cooccurrence.md", "cooccurrence.tex", "cooccurrence_by_session.csv", "events.csv", "cooccurrence.png"):
        assert (tmp_path / f).is_file()
    u = run_task(compose(["task=user_study"]), tmp_path / "us")
    assert [round(r["chi2"], 2) for r in u["rows"]] == [57.56, 5.02, 1.43, 9.61]


def test_graph_tasks(tiny_corpus_dir, cache, tmp_path):
    s = run_task(cfg_for("build_graph", tiny_corpus_dir, cache), tmp_path / "g")
    assert set(s["graphs"]) == {"female", "male"}
    for ch in ("female", "male"):
        gs = s["graphs"][ch]
        for key in ("num_frames", "num_key_states", "threshold", "num_states_before_scc", "num_edges_before_scc",
                    "num_states", "num_edges", "seconds", "w_v", "joint_weights"):
            assert gs[key] is not None
        from convsynth_jax.graph import load_graph

        e = load_graph(tmp_path / "g" / f"graph_{ch}.npz").edges_frame()
        assert list(e.columns) == ["source_file", "source_frame", "target_file", "target_frame", "cost", "synthetic"]
    run_task(cfg_for("table2", tiny_corpus_dir, cache, "task.ks=[2,3]"), tmp_path / "t2")
    t2 = pd.read_csv(tmp_path / "t2" / "table2.csv")
    assert len(t2) == 4 and (t2["states_after_scc"] <= t2["states_before_scc"]).all()
    run_task(cfg_for("figure4", tiny_corpus_dir, cache, "task.ks=[3]"), tmp_path / "f4")
    assert (tmp_path / "f4" / "figure4.png").is_file()
    # the figure script redraws from the CSVs alone
    r = subprocess.run([sys.executable, str(REPO / "experiments" / "paper" / "figure4.py"), str(tmp_path / "f4")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_build_graph_on_bvh_folder(tmp_path):
    from conftest import TEST_DATA

    s = run_task(compose(["task=build_graph", "corpus=bvh_folder", f"corpus.root={TEST_DATA}", "graph.k=3"]), tmp_path)
    assert s["num_frames"] > 0 and s["num_states"] <= s["num_states_before_scc"]
    assert (tmp_path / "graph.npz").is_file()


def test_synthesize_task_outputs_are_valid(tiny_corpus_dir, cache, tmp_path):
    from convsynth_jax.io import load_bvh
    from convsynth_jax.kinematics import forward_kinematics

    # a window both characters' searches solve under the paper's rules (preset=paper, the default), so
    # every check below runs: a search that fails here is a regression, not a reason to skip
    s = run_task(cfg_for("synthesize", tiny_corpus_dir, cache, "task.start=14", "task.duration=10"), tmp_path)
    for key in ("success", "search_seconds", "num_synthetic_transitions", "constraints_total", "constraints_met"):
        assert key in s
    report = json.loads((tmp_path / "report.json").read_text())
    assert set(report["characters"]) == {"female", "male"} and s["success"] is True
    for ch, r in report["characters"].items():
        assert r["success"] and not r.get("best_effort"), (ch, r.get("failure"))
        assert s["constraints_total"][ch] > 0                              # the window has constraints to meet
        assert s["constraints_met"][ch] == s["constraints_total"][ch]  # the independent checker agrees
        assert len(s["source_frames"][ch]) == 300
        m = load_bvh(tmp_path / f"{ch}.bvh")
        ours = np.asarray(forward_kinematics(m))
        np.testing.assert_allclose(independent_bvh_positions(tmp_path / f"{ch}.bvh")[:20], ours[:20], atol=1e-3)
        # no jumps: per-frame joint displacement within what the corpus itself shows
        jump = np.linalg.norm(np.diff(ours, axis=0), axis=-1).max()
        assert jump < 8.0, jump
        blinks = pd.read_csv(tmp_path / f"{ch}_blinks.csv")
        assert len(blinks) == 300 and blinks["blink"].between(0, 1).all() and blinks["blink"].max() > 0.5
    assert any(p.name.endswith("_input.wav") for p in tmp_path.iterdir())


def test_synthesize_task_best_effort_and_retiming(tiny_corpus_dir, cache, tmp_path):
    """With best effort and retiming every character gets motion; the summary's constraint counts are
    the independent checker's through the warp, and the report keeps the warp and the checker's details."""
    s = run_task(cfg_for("synthesize", tiny_corpus_dir, cache, "task.start=14", "task.duration=10",
                         "search.on_failure=best_effort", "search.retime_factor=0.2"), tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    for ch, r in report["characters"].items():
        assert r["success"], r
        det = r["checker"]["details"]
        assert s["constraints_met"][ch] == sum(d["met"] for d in det) and s["constraints_total"][ch] == len(det)
        if not r["best_effort"]:
            assert s["constraints_met"][ch] == s["constraints_total"][ch]
        if "warp" in r:
            k = r["warp"]
            assert k["output_frames"][0] == 0 and k["output_frames"][-1] == 299 and k["path_frames"][-1] == 299


def test_synthesize_condition_checks_the_conditions_constraints(tiny_corpus_dir, cache, tmp_path):
    """Under task.condition=no_lr the search is not asked to meet listener responses, so the checker's
    report counts none (it used to count them from the global search.use_lr), while a control under the
    default condition does count them on the same window."""
    counts = {}
    for cond in ("no_lr", "all"):
        out = tmp_path / cond
        out.mkdir()
        run_task(cfg_for("synthesize", tiny_corpus_dir, cache, "preset=quality", f"task.condition={cond}"), out)
        report = json.loads((out / "report.json").read_text())
        counts[cond] = sum(d["kind"] == "LR" for r in report["characters"].values() if r["success"]
                           for d in r["checker"]["details"])
    assert counts["no_lr"] == 0 and counts["all"] > 0, counts


def test_loo_sweep_collect_records_failures_and_figure_scripts(tiny_corpus_dir, cache, tmp_path):
    sweep = tmp_path / "multirun"
    for fold, cond in ((0, "all"), (0, "no_lr"), (0, "none"), (7, "all")):  # fold 7 does not exist: a failing job
        job = sweep / f"{fold}_{cond}"
        (job / ".hydra").mkdir(parents=True)
        (job / ".hydra" / "overrides.yaml").write_text(f"- fold={fold}\n- condition={cond}\n")
        s = run_task(compose(["experiment=loo_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                              f"fold={fold}", f"condition={cond}", "progress=false"]), job)
        assert s["success"] == (fold == 0)
    (sweep / "crashed" / ".hydra").mkdir(parents=True)
    (sweep / "crashed" / ".hydra" / "overrides.yaml").write_text("- fold=1\n- condition=no_hp\n")
    s = run_task(compose(["task=collect", f"task.dir={sweep}"]), tmp_path / "col")
    cases = pd.read_csv(tmp_path / "col" / "all_cases.csv")
    assert s["num_failed_jobs"] == 2  # the bad fold and the job that wrote nothing
    assert set(cases.loc[cases["status"] == "error", "fold"]) == {7, 1}
    ok = cases[cases["status"] == "ok"]
    assert set(ok["condition"]) == {"all", "no_lr", "none"} and len(ok) == 3 * 2 * 2
    rates = pd.read_csv(tmp_path / "col" / "success_rates.csv")
    assert set(rates["condition"]) == {"all", "no_lr", "none"}
    for script, out in (("success_rates.py", "success_rates.png"), ("table3.py", "table3.md"),
                        ("ablation.py", "ablation.png")):
        r = subprocess.run([sys.executable, str(REPO / "experiments" / "paper" / script), str(tmp_path / "col"), "--out",
                            str(tmp_path / "fig")], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert (tmp_path / "fig" / out).is_file()
