"""The main job on the tiny corpus, then every notebook executed against its outputs."""
import json
import os
from pathlib import Path

import pytest


NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("[!_]*.py"))


def test_main_job_outputs(main_run):
    out, s = main_run
    assert s["success"] and s["num_cases"] > 0
    report = (out / "report.md").read_text()
    for heading in ("Table 1", "motion_graph models", "success rate", "Timing"):
        assert heading in report
    assert len(list((out / "bvh").glob("*.bvh"))) > 0
    assert json.loads((out / "summary.json").read_text())["corpus_root"]


@pytest.mark.parametrize("nb", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(nb, main_run, tiny_corpus_dir):
    import jupytext
    from nbclient import NotebookClient

    out, _ = main_run
    os.environ["CONVSYNTH_NB_RESULTS"] = str(out)
    os.environ["CONVSYNTH_NB_CORPUS"] = str(tiny_corpus_dir)
    notebook = jupytext.read(nb)
    NotebookClient(notebook, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(nb.parent)}}).execute()
    errors = [o for c in notebook.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors
