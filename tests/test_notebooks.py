"""The main job on the tiny corpus, then every notebook executed as a user runs it: by
``convsynth task=notebooks path=RUN`` with no environment variables, each notebook in its own kernel
started in notebooks/, failing on an error or on a notebook that shows no figure (image/png)."""
import json
import os
from pathlib import Path

import pytest
import yaml

from convsynth_jax.config import compose, run_task

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("[!_]*.py"))
# corpus_overview runs below on a run that recorded its corpus as a relative path (the harder case)
ON_MAIN_RUN = [nb for nb in NOTEBOOKS if nb.stem != "corpus_overview"]


def test_main_job_outputs(main_run):
    out, s = main_run
    assert s["success"] and s["character_windows"] > 0
    assert Path(s["corpus_root"]).is_absolute()  # read later from other directories (a notebook's kernel)
    report = (out / "report.md").read_text()
    for heading in ("Table 1", "motion_graph models", "success rate", "Timing"):
        assert heading in report
    assert len(list((out / "bvh").glob("*.bvh"))) > 0


def _execute(name: str, run: Path, out: Path):
    """``convsynth task=notebooks path=RUN task.only=[NAME]``; the executed notebook, checked."""
    import nbformat

    assert not [k for k in os.environ if k.startswith("CONVSYNTH_NB")]  # nothing set behind the user's back
    s = run_task(compose(["task=notebooks", f"path={run}", f"task.only=[{name}]"]), out)
    assert s["success"] and [r["notebook"] for r in s["notebooks"]] == [name]
    nb = nbformat.read(out / f"{name}.ipynb", as_version=4)
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    errors = [o for o in outputs if o.get("output_type") == "error"]
    assert not errors, errors
    figures = [o for o in outputs if "image/png" in o.get("data", {})]
    assert figures, f"{name} shows no figure (no image/png output)"
    assert s["notebooks"][0]["figures"] == len(figures)
    assert (out / f"{name}.html").is_file()
    assert any("Reads:" in o.get("data", {}).get("text/markdown", "") for o in outputs), f"{name} does not say what it reads"
    return nb


@pytest.mark.parametrize("nb", ON_MAIN_RUN, ids=lambda p: p.stem)
def test_notebook_runs_as_a_user_runs_it(nb, main_run, tmp_path):
    out, _ = main_run
    _execute(nb.stem, out, tmp_path)


def test_corpus_overview_on_a_run_that_recorded_a_relative_corpus_path(main_run, tiny_corpus_dir, tmp_path):
    """A main run launched from a folder with the default cache_dir records its corpus as
    ``data_cache/...``, relative to that folder, while the notebook's kernel runs in notebooks/: the
    path is resolved against the folder the run was launched in (Hydra's runtime.cwd)."""
    launch = tmp_path / "launch"
    (launch / "data_cache").mkdir(parents=True)
    (launch / "data_cache" / "synthetic_tiny").symlink_to(tiny_corpus_dir, target_is_directory=True)
    run = launch / "outputs" / "main" / "2026-01-01_00-00-00"
    (run / ".hydra").mkdir(parents=True)
    summary = {**json.loads((main_run[0] / "summary.json").read_text()), "corpus_root": "data_cache/synthetic_tiny"}
    (run / "summary.json").write_text(json.dumps(summary))
    (run / ".hydra" / "hydra.yaml").write_text(yaml.safe_dump({"hydra": {"runtime": {"cwd": str(launch)}}}))
    _execute("corpus_overview", run, tmp_path / "nb")


def test_recorded_paths_resolve_without_a_hydra_record(tmp_path):
    """Without .hydra/hydra.yaml, a relative path is looked for beside the outputs/ folder holding the run."""
    from convsynth_jax.errors import MissingFileError
    from convsynth_jax.evaluation.runs import newest_run, resolve_recorded

    run = tmp_path / "outputs" / "main" / "2026-01-01_00-00-00"
    run.mkdir(parents=True)
    (run / "summary.json").write_text("{}")
    (tmp_path / "data_cache" / "c").mkdir(parents=True)
    assert resolve_recorded(run, "data_cache/c") == (tmp_path / "data_cache" / "c").resolve()
    assert resolve_recorded(run, "/abs/x") == Path("/abs/x")
    with pytest.raises(MissingFileError, match="elsewhere"):
        resolve_recorded(run, "elsewhere")
    assert newest_run(tmp_path, "main") == run and newest_run(tmp_path, "collect") is None


def test_notebooks_task_names_a_missing_run(tmp_path, monkeypatch):
    from convsynth_jax.errors import ConvSynthError

    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConvSynthError, match="no finished main run"):
        run_task(compose(["task=notebooks"]), tmp_path / "out")
    with pytest.raises(ConvSynthError, match="task.only"):
        run_task(compose(["task=notebooks", f"path={tmp_path}", "task.only=[nope]"]), tmp_path / "out")


def test_parameters_go_after_the_parameters_cell_or_first():
    import nbformat

    from convsynth_jax.tasks.notebooks import inject_parameters

    tagged = nbformat.v4.new_notebook(cells=[nbformat.v4.new_markdown_cell("# t"),
                                             nbformat.v4.new_code_cell("run = None", metadata={"tags": ["parameters"]}),
                                             nbformat.v4.new_code_cell("print(run)")])
    assert inject_parameters(tagged, {"run": "/r"}) and tagged.cells[2].source.endswith("run = '/r'")
    plain = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("print(run)")])
    assert not inject_parameters(plain, {"run": "/r"}) and plain.cells[0].source.endswith("run = '/r'")
