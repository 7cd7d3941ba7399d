"""Task ``notebooks``: execute every notebook against a finished run, into notebooks and HTML pages.

``convsynth task=notebooks [path=RUN] [task.converse=DIR] [task.benchmark=DIR]`` executes each
jupytext percent-format notebook of ``notebooks/`` (``task.dir``; files starting with ``_`` are
helpers) in a fresh Jupyter kernel whose working directory is the notebooks' folder, with the inputs
written into the cell after the one tagged ``parameters`` (papermill's convention): ``run`` = the main
run ``path`` (default: the newest ``outputs/main/*`` of the directory ``convsynth`` runs in),
``converse`` = a collected converse sweep, ``benchmark`` = a benchmark run (None: the notebook's own
default, see ``notebooks/_paths.py``). Writes ``<name>.ipynb`` (executed, with its outputs) and
``<name>.html`` per notebook and ``notebooks.csv`` (status, error, figures = image/png outputs,
seconds). A notebook that fails is written with its error and fails the task after all have run.

Needs the ``notebooks`` extra: ``pip install -e ".[notebooks]"`` (jupytext, nbclient, nbconvert,
ipykernel and a Jupyter front end to open the notebooks).
"""
from __future__ import annotations

import logging
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional

import pandas as pd

from ..errors import ConfigError, ConvSynthError, MissingFileError
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[2]
PARAMETERS_TAG = "parameters"


@dataclass(frozen=True)
class NotebooksSettings:
    """``conf/task/notebooks.yaml``."""

    name: str = "notebooks"
    dir: Optional[str] = None          # folder of the notebooks (null: notebooks/ of the checkout)
    only: Optional[List[str]] = None   # notebook names to run (null: all)
    converse: Optional[str] = None     # a collected converse sweep (task=collect output) for converse_sweep
    benchmark: Optional[str] = None    # a task=benchmark output folder for benchmark_leaderboard
    kernel: str = "python3"
    timeout_s: int = 600               # per cell
    html: bool = True


def _require_extra():
    try:
        import jupytext  # noqa: F401
        import nbclient  # noqa: F401
        import nbconvert  # noqa: F401
    except ImportError as e:
        raise ConfigError(f"task=notebooks needs the notebooks extra ({e.name} is missing): "
                          "pip install -e \".[notebooks]\"") from None


def notebook_files(folder: Path, only=None) -> list[Path]:
    """The notebooks of ``folder`` (``*.py`` not starting with ``_``), sorted; ``only``: these names."""
    if not folder.is_dir():
        raise MissingFileError("notebook folder not found (set task.dir=DIR)", folder)
    files = sorted(p for p in folder.glob("*.py") if not p.name.startswith("_"))
    if only:
        names = {p.stem for p in files}
        unknown = sorted(set(only) - names)
        if unknown:
            raise ConfigError(f"task.only names no notebook of {folder}: {unknown} (notebooks: {sorted(names)})")
        files = [p for p in files if p.stem in set(only)]
    if not files:
        raise MissingFileError("no notebooks (*.py) in the folder", folder)
    return files


def inject_parameters(nb, values: dict) -> bool:
    """Insert a cell setting ``values`` after the cell tagged ``parameters`` (tagged
    ``injected-parameters``, as papermill does); without such a cell, before the first cell. Returns
    whether the notebook has a parameters cell."""
    import nbformat

    src = "# Parameters given by convsynth task=notebooks\n" + "\n".join(f"{k} = {v!r}" for k, v in values.items())
    new = nbformat.v4.new_code_cell(src, metadata={"tags": ["injected-parameters"]})
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and PARAMETERS_TAG in cell.get("metadata", {}).get("tags", []):
            nb.cells.insert(i + 1, new)
            return True
    nb.cells.insert(0, new)
    return False


def outputs_of(nb, output_type: str | None = None, mime: str | None = None) -> list:
    """The outputs of the notebook's code cells (of ``output_type``, or holding data of ``mime``)."""
    out = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    if output_type:
        out = [o for o in out if o.get("output_type") == output_type]
    if mime:
        out = [o for o in out if mime in o.get("data", {})]
    return out


class _NoAltTextWarning(logging.Filter):
    """nbconvert's lab template does not read an image's alternative text from the output (the
    notebooks give one, JupyterLab shows it) and warns on every figure: not a fault of the notebook."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Alternative text is missing")


def execute_notebook(src: Path, out_dir: Path, values: dict, kernel: str, timeout_s: int, html: bool) -> dict:
    """Execute one notebook into ``out_dir/<name>.ipynb`` (and ``.html``); its row of ``notebooks.csv``."""
    import jupytext
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError

    t0 = time.perf_counter()
    nb = jupytext.read(src)
    injected = inject_parameters(nb, values)
    error = ""
    try:
        NotebookClient(nb, timeout=timeout_s, kernel_name=kernel,
                       resources={"metadata": {"path": str(src.parent)}}).execute()
    except CellExecutionError as e:
        text = re.sub(r"\x1b\[[0-9;]*m", "", str(e)).strip()   # the traceback's terminal colours
        error = text.splitlines()[-1] if text else type(e).__name__
    except Exception as e:  # noqa: BLE001 (a kernel that does not start or dies: reported like a failed cell)
        error = f"{type(e).__name__}: {e}"
    errors = outputs_of(nb, "error")
    if errors and not error:
        error = f"{errors[0].get('ename')}: {errors[0].get('evalue')}"
    with atomic_path(out_dir / f"{src.stem}.ipynb") as tmp:
        nbformat.write(nb, str(tmp))
    if html:
        from nbconvert import HTMLExporter

        exporter = HTMLExporter()
        quiet = _NoAltTextWarning()
        exporter.log.addFilter(quiet)
        try:
            body, _ = exporter.from_notebook_node(nb)
        finally:
            exporter.log.removeFilter(quiet)
        write_text_atomic(out_dir / f"{src.stem}.html", body)
    figures = len(outputs_of(nb, mime="image/png"))
    return {"notebook": src.stem, "status": "error" if error else "ok", "error": error, "figures": figures,
            "parameters_cell": injected, "seconds": time.perf_counter() - t0}


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..evaluation.runs import newest_run, read_summary

    settings = task_settings(cfg)
    _require_extra()
    folder = Path(settings.dir) if settings.dir else REPO / "notebooks"
    files = notebook_files(folder.resolve(), settings.only)
    run_dir = Path(cfg.path) if cfg.get("path") else newest_run(Path.cwd(), "main")
    if run_dir is None:
        raise MissingFileError("no finished main run here: run `convsynth` first or give path=RUN",
                               Path.cwd() / "outputs" / "main")
    run_dir = run_dir.resolve()
    read_summary(run_dir)  # a finished run, or an error naming its folder
    values = {"run": str(run_dir),
              "converse": str(Path(settings.converse).resolve()) if settings.converse else None,
              "benchmark": str(Path(settings.benchmark).resolve()) if settings.benchmark else None}
    rows = []
    for f in files:
        log.info("executing %s against %s", f.name, run_dir)
        row = execute_notebook(f, out_dir, values, settings.kernel, settings.timeout_s, settings.html)
        if row["status"] == "error":
            log.error("%s: %s", f.name, row["error"])
        elif row["figures"] == 0:
            log.warning("%s: ran without showing a figure", f.name)
        rows.append(row)
    table = pd.DataFrame(rows)
    with atomic_path(out_dir / "notebooks.csv") as tmp:
        table.to_csv(tmp, index=False)
    print(table[["notebook", "status", "figures", "seconds", "error"]].to_string(index=False))
    failed = table[table["status"] == "error"]
    if len(failed):
        raise ConvSynthError(f"{len(failed)} of {len(table)} notebooks failed: "
                             + "; ".join(f"{r.notebook}: {r.error}" for r in failed.itertuples())
                             + f" (executed notebooks in {out_dir})", run_dir)
    return {"success": True, "run": str(run_dir), "notebooks": rows, "out_dir": str(out_dir)}
