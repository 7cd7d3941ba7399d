"""What the notebooks read and how they show figures.

Each notebook has a cell tagged ``parameters`` naming its inputs (``run = None`` and so on);
``convsynth task=notebooks [path=RUN]`` executes every notebook with the values it was given written
in a cell after that one (papermill's convention). Left at None, a notebook
opened by hand reads the newest run of the checkout (``outputs/<task>/<stamp>``, the folder
``convsynth`` writes when run from the repository's root) and, where a notebook has one, the
project's stored result in ``experiments/results/``.
"""
from __future__ import annotations

import io
from pathlib import Path

REPO = Path.cwd().parent if Path.cwd().name == "notebooks" else Path.cwd()
STORED = REPO / "experiments" / "results"


def results_dir(run=None) -> Path:
    """The main run to read: ``run`` when given, else the newest ``outputs/main/*`` of the checkout."""
    from convsynth_jax.evaluation.runs import newest_run

    if run:
        return Path(run).resolve()
    found = newest_run(REPO, "main")
    if found is None:
        raise FileNotFoundError(f"no finished main run under {REPO / 'outputs' / 'main'}: run `convsynth` first, "
                                "or `convsynth task=notebooks path=RUN` to execute the notebooks against RUN")
    return found


def corpus_dir(run=None) -> Path:
    """The corpus the main run used: its summary's ``corpus_root``, resolved against the directory the
    run was launched in when it is relative (runs written before the summary recorded it absolute)."""
    from convsynth_jax.evaluation.runs import read_summary, resolve_recorded

    d = results_dir(run)
    return resolve_recorded(d, read_summary(d)["corpus_root"])


def newest(task: str, holding: str, stored: str | None = None, given=None) -> Path:
    """The file ``holding`` to read: in folder ``given`` when set; else in the newest
    ``outputs/<task>/*`` of the checkout that holds it; else the stored result
    ``experiments/results/<stored>``."""
    from convsynth_jax.evaluation.runs import newest_run

    if given:
        return Path(given).resolve() / holding
    found = newest_run(REPO, task, holding)
    if found is not None:
        return found / holding
    if stored and (STORED / stored).is_file():
        return STORED / stored
    raise FileNotFoundError(f"no {holding} under {REPO / 'outputs' / task}"
                            + (f" nor {STORED / stored}" if stored else ""))


def reads(*files) -> None:
    """Say what the notebook reads (a Markdown list of the files), as its first output."""
    from IPython.display import Markdown, display

    display(Markdown("**Reads:**\n\n" + "\n".join(f"- `{Path(f).resolve()}`" for f in files)))


def show(fig, dpi: int = 100) -> None:
    """Show a figure of ``convsynth_jax.figures`` inline as a PNG. Those figures are made with
    matplotlib's object-oriented API, not pyplot, so Jupyter would show only their text repr
    (``<Figure size ... with 1 Axes>``); a pyplot figure is closed after, so that it is not shown twice."""
    import matplotlib.pyplot as plt
    from IPython.display import Image, display

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    titles = [t for t in [fig.get_suptitle()] + [ax.get_title() for ax in fig.axes] if t]
    display(Image(data=buf.getvalue(), format="png", alt="; ".join(titles) or "figure"))
