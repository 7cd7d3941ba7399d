"""Seams of collected leave-one-out runs in two readings of the seam goal (<= 1 on every window with a
synthetic transition), read from a run's ``all_cases.csv`` beside its success rates and co-occurrence:

* ``window`` (the metric as coded, ``evaluation.metrics.seam_ratio``): the largest root-relative
  acceleration within 3 frames of a transition over the ground-truth *window's* largest;
* ``recording`` ("the largest in the held-out recording"): the same peak over the largest of the
  character's whole held-out recording, computed from the first.

``experiments/analysis/seam_summary.py`` writes the table of several runs.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..kinematics import forward_kinematics
from .metrics import root_relative_acceleration

BLEND_MARGIN = 0.01  # two forward-kinematics calls in float32 differ by less than this


def _max_acc(motion) -> float:
    return float(root_relative_acceleration(np.asarray(forward_kinematics(motion), np.float64), motion.fps).max())


def seam_readings(cases: pd.DataFrame, ann, fps: float) -> pd.DataFrame:
    """The windows of ``cases`` (a collected ``all_cases.csv``) with a seam, with the ground truth's
    largest root-relative acceleration over the window (``gt_window_max``) and over the character's
    whole held-out recording (``gt_recording_max``, from ``ann``: session -> role -> annotation), and
    the seam in the recording reading: ``seam_ratio_recording`` = seam_ratio * window max / recording max."""
    s = cases[cases["seam_ratio"].notna()].copy()
    rec, win = {}, []
    for r in s.itertuples():
        m = ann[r.session][r.role].motion
        if (r.session, r.role) not in rec:
            rec[(r.session, r.role)] = _max_acc(m)
        f0 = int(round(r.window_start * fps))
        f1 = f0 + int(round((r.window_end - r.window_start) * fps))
        win.append(_max_acc(m.slice(f0, f1)))
    s["gt_window_max"] = win
    s["gt_recording_max"] = [rec[(a, b)] for a, b in zip(s["session"], s["role"])]
    s["seam_ratio_recording"] = s["seam_ratio"] * s["gt_window_max"] / s["gt_recording_max"]
    return s


def seam_run_summary(name: str, d: Path, ann, fps: float) -> dict:
    """One collected leave-one-out run (folder ``d``: all_cases.csv, success_rates.csv,
    cooccurrence_by_condition.csv): seams over 1, worst and median in both readings, where the seams
    over 1 come from (source content alone >= 1, or the blend adds more than :data:`BLEND_MARGIN`; runs
    with ``seam_content_ratio``), success per condition, the co-occurrence rows that differ from the
    ground truth's at p < 0.05, jerk against the ground truth's, transitions per window, worst windows."""
    d = Path(d)
    cases = pd.read_csv(d / "all_cases.csv")
    s = seam_readings(cases, ann, fps)
    out = {"run": name, "dir": str(d), "windows_with_transitions": int(len(s))}
    for key, col in (("window", "seam_ratio"), ("recording", "seam_ratio_recording")):
        out[f"{key}_over_1"] = int((s[col] > 1).sum())
        out[f"{key}_worst"] = float(s[col].max()) if len(s) else float("nan")
        out[f"{key}_median"] = float(s[col].median()) if len(s) else float("nan")
    if "seam_content_ratio" in s:
        over = s[s["seam_ratio"] > 1]
        out["over_1_content_at_least_1"] = int((over["seam_content_ratio"] >= 1).sum())
        out["over_1_blend"] = int((over["seam_ratio"] > np.maximum(1.0, over["seam_content_ratio"])
                                   * (1 + BLEND_MARGIN)).sum())
        out["blend_worst"] = float((s["seam_ratio"] / s["seam_content_ratio"]).max())
    # stored sweeps collected before the columns said windows call them cases
    rates = pd.read_csv(d / "success_rates.csv").rename(columns={"solved": "solved_windows", "cases": "windows"})
    out["success"] = {r.condition: f"{r.solved_windows}/{r.windows}" for r in rates.itertuples()}
    co = pd.read_csv(d / "cooccurrence_by_condition.csv")
    sig = co[co["p_value"] < 0.05]
    out["cooccurrence_significant"] = {c: [f"{r.character} {r.hypothesis} {r.synth_rate:.2f} vs {r.gt_rate:.2f}"
                                           for r in g.itertuples()] for c, g in sig.groupby("condition")}
    ok = cases[cases["success"].astype(bool)]
    out["mean_jerk_ratio"] = float(ok["jerk"].mean() / ok["gt_jerk"].mean()) if "jerk" in ok else float("nan")
    out["synthetic_transitions_per_window"] = float(ok["num_synthetic_transitions"].mean())
    worst = s.sort_values("seam_ratio", ascending=False).head(5)
    out["worst_windows"] = [f"fold {r.fold} {r.condition} {r.session} @{r.window_start:g}s {r.character}: "
                            f"{r.seam_ratio:.2f} (recording {r.seam_ratio_recording:.2f}"
                            + (f", content {r.seam_content_ratio:.2f})" if "seam_content_ratio" in s else ")")
                            for r in worst.itertuples()]
    return out


def seam_summary_lines(res: list[dict]) -> list[str]:
    """Markdown of :func:`seam_run_summary` results: the seams in both readings beside success, jerk and
    transitions; where the seams over 1 come from; the significant co-occurrence rows and worst windows."""
    lines = ["| run | windows with transitions | window reading: > 1 / worst / median | recording reading: > 1 / worst "
             "/ median | solved all / no_lr / no_hp / none | jerk vs gt | transitions per window |", "|---" * 7 + "|"]
    for r in res:
        sc = r["success"]
        lines.append(f"| {r['run']} | {r['windows_with_transitions']} | {r['window_over_1']} / {r['window_worst']:.2f} / "
                     f"{r['window_median']:.2f} | {r['recording_over_1']} / {r['recording_worst']:.2f} / "
                     f"{r['recording_median']:.2f} | {' / '.join(sc.get(c, '-') for c in ('all', 'no_lr', 'no_hp', 'none'))}"
                     f" | {r['mean_jerk_ratio']:.2f} | {r['synthetic_transitions_per_window']:.1f} |")
    lines.append("")
    if any("over_1_blend" in r for r in res):
        lines += ["| run | window reading > 1 | of which source content alone >= 1 | of which the blend adds > 1% over "
                  "max(1, content) | largest seam / content |", "|---" * 5 + "|"]
        lines += [f"| {r['run']} | {r['window_over_1']} | {r['over_1_content_at_least_1']} | {r['over_1_blend']} | "
                  f"{r['blend_worst']:.2f} |" for r in res if "over_1_blend" in r]
        lines.append("")
    for r in res:
        lines.append(f"**{r['run']}**: co-occurrence rows with p < 0.05 (synth vs ground truth): "
                     + "; ".join(f"{c}: {', '.join(v)}" for c, v in r["cooccurrence_significant"].items()))
        lines.append("")
        lines.append("worst windows: " + "; ".join(r["worst_windows"]))
        lines.append("")
    return lines
