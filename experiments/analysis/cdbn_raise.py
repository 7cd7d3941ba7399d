"""Why the CDBN hand model's Bandai2 raises were misclassified, and what the fix
changes: the Table V/VI protocol of the hand model (``hand_evaluation``: state choice on the
validation fold, ``--test-folds`` test folds, nearest-centroid classifier fitted on the training
turns' original segments) on the same clips under the four labellings

* ``gestures``: ``pooled`` (other / raise / wave: the former labels) or ``per_side`` (one constraint
  per gesture and side, as the paper's one prototypical gesture per constraint);
* ``span``: ``fraction`` (all but the first and last 15% of a clip: the former labels) or ``motion``
  (the frames whose arms are away from rest, ``cdbn.hand_eval.gesture_span``).

For each: the share of synthesized segments classified as their own gesture (``exact``: with its
side when the labels have one), as their kind (raise / wave, side left out), and the same
classifier on the original motion of those segments (how far the measure can be trusted). Also the
mean arm speed (degrees per frame, summed over the 10 angles) inside and outside the gesture span
per clip type, which shows where a 2 s raise lifts and lowers its arm.

    python experiments/analysis/cdbn_raise.py [--clips 160] [--test-folds 3]

Writes experiments/results/cdbn_raise.json and cdbn_raise.md (with manifests).
"""
import argparse
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import numpy as np  # noqa: E402
from _bench import SHARED, write, write_markdown  # noqa: E402

from convsynth_jax.cdbn.hand_eval import (  # noqa: E402
    bandai_constraints,
    bandai_hand_turns,
    gesture_kind,
    hand_evaluation,
)
from convsynth_jax.cdbn.params import CDBNFeatureParams  # noqa: E402

LABELLINGS = (("pooled", "fraction"), ("pooled", "motion"), ("per_side", "fraction"), ("per_side", "motion"))


def arm_speed_by_type(turns) -> dict:
    """Per clip type: mean arm speed (deg/frame, summed over the angles) inside and outside the span."""
    out = {}
    for typ in sorted({t.name.split("_")[1] for t in turns}):
        mine = [t for t in turns if t.name.split("_")[1] == typ]
        speed = [np.abs(np.diff(t.motion, axis=0)).sum(1) for t in mine]
        inside = np.concatenate([s[t.constraints[1:] > 0] for s, t in zip(speed, mine)])
        outside = np.concatenate([s[t.constraints[1:] == 0] for s, t in zip(speed, mine)])
        out[typ] = {"clips": len(mine), "frames": int(sum(len(t.motion) for t in mine)),
                    "other_fraction": float(np.mean(np.concatenate([t.constraints == 0 for t in mine]))),
                    "speed_in_span": float(inside.mean()), "speed_outside_span": float(outside.mean())}
    return out


def summarize(res: dict) -> dict:
    out = {}
    for model, rows in res["gesture_predictions"].items():
        out[model] = {}
        for kind in ("raise", "wave"):
            mine = [r for r in rows if gesture_kind(r["truth"]) == kind]
            out[model][kind] = {"n": len(mine),
                                "exact": float(np.mean([r["predicted"] == r["truth"] for r in mine])),
                                "kind": float(np.mean([gesture_kind(r["predicted"]) == kind for r in mine])),
                                "predicted_as": dict(Counter(r["predicted"] for r in mine))}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", type=int, default=160)
    ap.add_argument("--test-folds", type=int, default=3)
    args = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    bvh, wav = SHARED / "bandai2" / "bvh", SHARED / "speech" / "acoustic_corpus.wav"
    fp = CDBNFeatureParams()
    ep = {"folds": 10, "jdbn_grid": (8, 12), "cdbn_grid": (3, 4), "max_test_folds": args.test_folds}
    result = {"clips": args.clips, "eval": ep, "labellings": {}}
    lines = ["| constraints | span | model | states | raise exact | raise kind | wave exact | wave kind |",
             "|---|---|---|---|---|---|---|---|"]
    for gestures, span in LABELLINGS:
        t0 = time.perf_counter()
        turns, rig = bandai_hand_turns(bvh, wav, fp, max_clips=args.clips, gestures=gestures, span=span)
        res = hand_evaluation(turns, rig, bandai_constraints(gestures), ep)
        acc = summarize(res)
        states = {r["model"]: r["states"] for r in res["table"]}
        result["labellings"][f"{gestures}/{span}"] = {
            "accuracy": acc, "chosen_states": res["chosen_states"], "table": res["table"],
            "frames_per_constraint": res["frames_per_constraint"], "arm_speed": arm_speed_by_type(turns),
            "seconds": time.perf_counter() - t0}
        for model, label in (("original", "original motion"), ("jdbn", "jDBN"), ("cdbn", "CDBN")):
            a = acc[model]
            st = {"jdbn": states.get("Baseline (jDBN)"), "cdbn": states.get("CDBN-Ges")}.get(model)
            lines.append(f"| {gestures} | {span} | {label} | {'' if st is None else f'{st:.0f}'} | "
                         f"{a['raise']['exact']:.2f} | {a['raise']['kind']:.2f} | "
                         f"{a['wave']['exact']:.2f} | {a['wave']['kind']:.2f} |")
        print("\n".join(lines[-3:]), flush=True)
    n = result["labellings"]["per_side/motion"]["accuracy"]["cdbn"]
    lines += ["", f"Segments per test: raise {n['raise']['n']}, wave {n['wave']['n']} "
              f"({args.clips} clips, {args.test_folds} test folds). exact: classified as its own gesture "
              "(with its side under per_side); kind: as a raise / wave of any side."]
    write("cdbn_raise", result)
    write_markdown("cdbn_raise", lines)


if __name__ == "__main__":
    main()
