"""Seams of collected leave-one-out runs, read from their ``all_cases.csv``, beside
the success rates and the co-occurrence of the same runs.

    python experiments/analysis/seam_summary.py --cache DIR --out FILE.md NAME=RESULT_DIR [NAME=RESULT_DIR ...]

Two readings of the seam goal (<= 1 on every window with a synthetic transition):
* ``window`` (the metric as coded, ``evaluation.metrics.seam_ratio``): the largest root-relative
  acceleration within 3 frames of a transition over the ground-truth *window's* largest;
* ``recording`` ("the largest in the held-out recording"): the same peak over
  the largest of the character's whole held-out recording. It is computed here from the first:
  seam_ratio * window max / recording max (both from the annotated corpus of ``--cache``).
Where the seams over 1 come from (runs with the ``seam_content_ratio`` column,
``evaluation.metrics.seam_content_ratio``: the played source clips' own acceleration at the seam
frames on the same scale): ``content`` counts the windows over 1 whose source content alone is at
least 1 (any blend inherits it), ``blend`` those whose seam exceeds 1 and its content by more than
``BLEND_MARGIN`` (1%: the two are computed through different forward-kinematics calls, float32).
Co-occurrence: the rows of ``cooccurrence_by_condition.csv`` where the synthesized rate differs
from the ground truth's at p < 0.05 (chi-square), per condition.
"""
import argparse
from pathlib import Path

from convsynth_jax.api import annotated_corpus, write_result, write_result_markdown
from convsynth_jax.config import default_params
from convsynth_jax.evaluation.seam_summary import seam_run_summary, seam_summary_lines

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cache", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("runs", nargs="+", help="NAME=DIR with all_cases.csv, success_rates.csv, cooccurrence_by_condition.csv")
    args = ap.parse_args()
    params = default_params([f"cache_dir={args.cache}", "progress=false"])
    _, ann = annotated_corpus(params)
    fps = float(params.features.fps)
    res = [seam_run_summary(n, Path(p), ann, fps) for n, p in (r.split("=", 1) for r in args.runs)]
    out = Path(args.out)
    write_result_markdown(out.stem, seam_summary_lines(res), folder=out.parent)
    write_result(out.stem, res, folder=out.parent)
