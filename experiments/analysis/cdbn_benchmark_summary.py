"""Head-scope summary of a ``task=benchmark`` run with CDBN / jDBN systems: per system, the head
point's jerk over the ground truth's and the raw FGD over random playback's (the goals: 0.5-2x and
at most 3x), with the leaderboard copied beside it.

    convsynth task=benchmark 'task.folds=[0,1,2]' task.systems.motion_graph=null \
      '+task.systems.cdbn_quality={system:cdbn,condition:cdbn,preset:quality}' \
      '+task.systems.jdbn={system:cdbn,condition:jdbn}' \
      '+task.systems.jdbn_quality={system:cdbn,condition:jdbn,preset:quality}' hydra.run.dir=OUT
    python experiments/analysis/cdbn_benchmark_summary.py OUT/leaderboard.csv --name NAME \
      --seconds S --load "L1 L2" --override task.folds=[0,1,2] ...

Writes experiments/results/<name>.json, .md, .csv (with manifests).
"""
import argparse
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import pandas as pd  # noqa: E402
from _bench import RESULTS, write, write_markdown  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("leaderboard")
    ap.add_argument("--name", required=True)
    ap.add_argument("--seconds", type=float, default=None)
    ap.add_argument("--load", default="")
    ap.add_argument("--override", nargs="*", default=[])
    args = ap.parse_args()
    df = pd.read_csv(args.leaderboard)
    head = df[df.scope == "head"].pivot_table(index="system", columns="metric", values="value", aggfunc="first")
    windows = df[(df.scope == "head") & (df.metric == "jerk")].set_index("system")["n_windows"]
    gt_jerk, rp_fgd = head.loc["ground_truth", "jerk"], head.loc["random_playback", "fgd_raw"]
    rows = {s: {"jerk": float(r["jerk"]), "jerk_over_ground_truth": float(r["jerk"] / gt_jerk),
                "fgd_raw": float(r["fgd_raw"]), "fgd_raw_over_random_playback": float(r["fgd_raw"] / rp_fgd),
                "windows": int(windows.get(s, 0))}
            for s, r in head.iterrows()}
    result = {"scope": "head", "rows": rows, "wall_seconds": args.seconds, "load_during_run": args.load,
              "goals": {"jerk_over_ground_truth": [0.5, 2.0], "fgd_raw_over_random_playback": 3.0}}
    write(args.name, result, overrides=args.override)
    lines = ["| system | head-point jerk | / ground truth | raw FGD (head) | / random playback |", "|---|---|---|---|---|"]
    lines += [f"| {s} | {r['jerk']:.3g} | {r['jerk_over_ground_truth']:.2f} | {r['fgd_raw']:.3g} | "
              f"{r['fgd_raw_over_random_playback']:.2f} |" for s, r in rows.items()]
    write_markdown(args.name, lines, overrides=args.override)
    shutil.copy(args.leaderboard, RESULTS / f"{args.name}_leaderboard.csv")


if __name__ == "__main__":
    main()
