"""The objective evaluation of Sec. VIII on a turn dataset: 10-fold cross-validation with one
validation fold choosing the number of states, jDBN versus CDBN (CCA_m, CCA_ms, KLD, LLR, per-turn
means and SDs), the LBG versus random initialization comparison (Fig. 6), the sparse versus shared
transition distance (Eq. 8) and the nod/shake accuracy of synthesized gestures (Table VI analogue).

State selection (ours, following Fig. 9's "saturation"): the smallest N whose validation CCA_m is
within ``cca_slack`` of the best and whose LLR is within ``llr_slack`` (relative) of the best.
"""
from __future__ import annotations

import itertools
import logging
import time

import numpy as np
from scipy import stats

from .cdbn import (
    TrainedModel,
    train_cdbn,
    train_jdbn,
    train_shared,
    transition_distance,
)
from .dataset import Turn
from .em import e_step, fit_em, make_batch
from .evaluate import cca, gaussian_kld, gesture_features
from .params import CDBNEvalParams, CDBNParams, TrainParams  # noqa: F401  (CDBNEvalParams: the protocol's settings)
from .synthesize import expected_motion, keypoint_smooth, state_posteriors, state_posteriors_batch

log = logging.getLogger(__name__)


def fit(kind: str, turns: list[Turn], n: int, p: CDBNParams, train: TrainParams | None = None) -> TrainedModel:
    train = train or p.train
    seqs = [t.observations() for t in turns]
    cons = [t.constraints for t in turns]
    ds, dm = turns[0].speech.shape[1], turns[0].motion.shape[1]
    sd, md = tuple(range(ds)), tuple(range(ds, ds + dm))
    from .features import FEATURE_LAYOUT

    layout = FEATURE_LAYOUT if ds + dm == len(FEATURE_LAYOUT) else ()
    if kind == "jdbn":
        return train_jdbn(seqs, n, sd, md, train, layout)
    if kind == "shared":
        return train_shared(seqs, cons, n, sd, md, train, p.constraints, layout)
    if kind == "cdbn":
        return train_cdbn(seqs, cons, n, sd, md, train, p.constraints, p.constrain.merge_threshold,
                          p.constrain.shared_state, layout)
    raise ValueError(kind)


def synthesize_turn(tm: TrainedModel, turn: Turn, p: CDBNParams, motion_norm=None, rig=None,
                    gamma: np.ndarray | None = None) -> np.ndarray:
    """Synthesized motion (T, d_m) in z-units of the turn's subject; smoothed with key points in degree
    space when ``motion_norm`` (the subject's motion Normalization) is given: the head at
    ``keypoints_per_second``, or, with ``rig`` (an ArmRig: the hand stream), each arm joint at
    ``hand_keypoints_per_second``. ``gamma``: the turn's state posteriors when already computed."""
    if gamma is None:
        cons = turn.constraints if tm.model.num_constraints > 1 else None
        gamma = state_posteriors(tm.model, turn.speech, cons, p.synth.posterior)
    g = gamma
    z = expected_motion(tm.model, g)
    if motion_norm is None:
        return z
    deg = motion_norm.invert(z)
    if rig is not None:
        from .hands import smooth_arm_angles

        return motion_norm.apply(smooth_arm_angles(deg, rig, p.features.fps, p.synth.hand_keypoints_per_second))
    q = keypoint_smooth(deg, p.features.fps, p.synth.keypoints_per_second)
    from .features import head_rotation_from_quat

    return motion_norm.apply(head_rotation_from_quat(q))


def loglik_per_frame(tm: TrainedModel, turns: list[Turn]) -> float:
    cons = [t.constraints for t in turns] if tm.model.num_constraints > 1 else None
    b = make_batch([t.observations() for t in turns], cons, pack=True)
    return e_step(tm.model, b).log_likelihood / b.num_frames


def score(tm: TrainedModel, turns: list[Turn], p: CDBNParams, norms: dict, rig=None) -> dict:
    rows, synth = [], []
    cons = [t.constraints for t in turns] if tm.model.num_constraints > 1 else None
    gammas = state_posteriors_batch(tm.model, [t.speech for t in turns], cons, p.synth.posterior)
    for t, g in zip(turns, gammas):
        s = synthesize_turn(tm, t, p, norms[t.subject][1], rig, g)
        synth.append(s)
        rows.append({"turn": t.name, "cca_m": cca(t.motion, s), "cca_ms": cca(t.speech, s),
                     "cca_orig_ms": cca(t.speech, t.motion)})
    orig = np.concatenate([t.motion for t in turns])
    syn = np.concatenate(synth)
    return {"rows": rows, "kld": gaussian_kld(orig, syn), "llr": loglik_per_frame(tm, turns), "synth": synth}


def choose_states(values: dict, cca_slack: float, llr_slack: float) -> int:
    """values: N -> (cca_m, llr) on the validation fold."""
    ns = sorted(values)
    best_c = max(values[n][0] for n in ns)
    best_l = max(values[n][1] for n in ns)
    for n in ns:
        c, ll = values[n]
        if c >= best_c - cca_slack and ll >= best_l - llr_slack * abs(best_l):
            return n
    return max(ns, key=lambda n: values[n][0])


def gesture_segments(turns: list[Turn], motions: list[np.ndarray], names: tuple, fps: float,
                     rng: np.random.Generator | None = None, with_other: bool = True, sources: list | None = None):
    """(segments, labels) of constraint runs other than code 0 ('other'), plus one random 'other'
    window of 20-44 frames (at most the run) inside each 'other' run of 30 frames or more when
    ``with_other``; ``sources``, when given, receives each segment's
    turn name."""
    segs, labels = [], []
    for t, m in zip(turns, motions):
        c = t.constraints
        edges = np.flatnonzero(np.diff(np.concatenate([[-1], c, [-1]])))
        for a, b in itertools.pairwise(edges):
            if c[a] != 0 and b - a >= 6:
                segs.append(m[a:b])
                labels.append(names[c[a]])
                if sources is not None:
                    sources.append(t.name)
            elif c[a] == 0 and with_other and b - a >= 30 and rng is not None:
                L = min(int(rng.integers(20, 45)), b - a)  # inside the run: never into the next gesture
                s0 = int(rng.integers(a, b - L + 1))
                segs.append(m[s0:s0 + L])
                labels.append(names[0])
                if sources is not None:
                    sources.append(t.name)
    return segs, labels


def hand_gesture_features(angles: np.ndarray, fps: float) -> np.ndarray:
    """Hand-stream segment features (ours, for the Table VI analogue of the hand model): the mean of
    each of the 10 angles (/30 degrees) and the log band SD of each -> (20,)."""
    from .evaluate import band_sd

    return np.concatenate([np.asarray(angles).mean(0) / 30.0, np.log(band_sd(angles, fps) + 1e-3)])


def run_cdbn_evaluation(turns: list[Turn], norms: dict, p: CDBNParams, ep: CDBNEvalParams, progress=None, rig=None) -> dict:
    """Everything of the summary except file writing. Returns a dict with tables, per-turn rows,
    the fold-1 models and held-out turns. ``rig`` (an ArmRig): the turns carry the hand stream (hand
    smoothing, hand gesture features)."""
    from .evaluate import NearestCentroid

    feat = (lambda s, fps: hand_gesture_features(s, fps)) if rig is not None else gesture_features
    t0 = time.perf_counter()
    rng = np.random.default_rng(ep.seed)
    order = rng.permutation(len(turns))
    parts = [order[i::ep.folds] for i in range(ep.folds)]
    pick = lambda idx: [turns[i] for i in idx]
    phases = {}
    # --- validation: fold 0 held out, folds 1..9 train
    val, rest = pick(parts[0]), pick(np.concatenate(parts[1:]))
    chosen, curves = {}, {}
    for kind, grid in (("jdbn", ep.jdbn_grid), ("cdbn", ep.cdbn_grid)):
        vals = {}
        for n in grid:
            tm = fit(kind, rest, n, p)
            sc = score(tm, val, p, norms, rig)
            vals[n] = (float(np.mean([r["cca_m"] for r in sc["rows"]])), float(sc["llr"]))
            log.info("validation %s N=%d: CCA_m %.3f, LLR %.3f", kind, n, *vals[n])
        curves[kind] = {int(n): {"cca_m": v[0], "llr": v[1]} for n, v in vals.items()}
        chosen[kind] = choose_states(vals, ep.cca_slack, ep.llr_slack)
    phases["validation"] = time.perf_counter() - t0
    # --- test folds 1..9: train on the other nine partitions (validation included)
    per_turn = {"jdbn": [], "cdbn": []}
    kld = {"jdbn": [], "cdbn": []}
    llr = {"jdbn": [], "cdbn": []}
    gest = {"jdbn": ([], [], []), "cdbn": ([], [], []), "original": ([], [], [])}
    states, params_n = {"jdbn": [], "cdbn": []}, {"jdbn": [], "cdbn": []}
    folds_out = {}
    test_folds = list(range(1, ep.folds))[: ep.max_test_folds]
    for f in test_folds:
        test = pick(parts[f])
        train = pick(np.concatenate([parts[i] for i in range(ep.folds) if i != f]))
        # classifier of gestures fitted on the original training segments
        segs, labs = gesture_segments(train, [norms[t.subject][1].invert(t.motion) for t in train], p.constraints,
                                      p.features.fps, rng)
        clf = NearestCentroid(np.stack([feat(s, p.features.fps) for s in segs]), np.asarray(labs))
        # the classifier on the test turns' original motion: how far it can be trusted (ours)
        src = []
        gs, gl = gesture_segments(test, [norms[t.subject][1].invert(t.motion) for t in test], p.constraints,
                                  p.features.fps, None, with_other=False, sources=src)
        if gs:
            pred = clf.predict(np.stack([feat(s, p.features.fps) for s in gs]))
            gest["original"][0].extend(gl)
            gest["original"][1].extend(pred.tolist())
            gest["original"][2].extend(src)
        for kind in ("jdbn", "cdbn"):
            tm = fit(kind, train, chosen[kind], p)
            sc = score(tm, test, p, norms, rig)
            per_turn[kind] += [{**r, "fold": f} for r in sc["rows"]]
            kld[kind].append(sc["kld"])
            llr[kind].append(sc["llr"])
            states[kind].append(tm.model.num_states)
            params_n[kind].append(tm.num_parameters)
            deg = [norms[t.subject][1].invert(s) for t, s in zip(test, sc["synth"])]
            src = []
            gs, gl = gesture_segments(test, deg, p.constraints, p.features.fps, None, with_other=False, sources=src)
            if gs:
                pred = clf.predict(np.stack([feat(s, p.features.fps) for s in gs]))
                gest[kind][0].extend(gl)
                gest[kind][1].extend(pred.tolist())
                gest[kind][2].extend(src)
            if f == test_folds[0]:
                folds_out[kind] = tm
                folds_out[f"{kind}_synth"] = sc["synth"]
        if f == test_folds[0]:
            folds_out["test"] = test
            folds_out["train"] = train
        log.info("fold %d done (%.0f s)", f, time.perf_counter() - t0)
    phases["test_folds"] = time.perf_counter() - t0 - phases["validation"]
    table = []
    for kind in ("jdbn", "cdbn"):
        cm = np.array([r["cca_m"] for r in per_turn[kind]])
        cms = np.array([r["cca_ms"] for r in per_turn[kind]])
        table.append({"model": {"jdbn": "Baseline (jDBN)", "cdbn": "CDBN-Ges"}[kind],
                      "states": float(np.mean(states[kind])), "states_per_constraint": chosen[kind],
                      "params": float(np.mean(params_n[kind])), "cca_m_mean": float(cm.mean()), "cca_m_sd": float(cm.std()),
                      "cca_ms_mean": float(cms.mean()), "cca_ms_sd": float(cms.std()),
                      "kld": float(np.mean(kld[kind])), "llr": float(np.mean(llr[kind]))})
    acc = {}
    for kind in gest:
        truth, pred = np.array(gest[kind][0]), np.array(gest[kind][1])
        acc[kind] = {lab: {"n": int((truth == lab).sum()),
                           "accuracy": float((pred[truth == lab] == lab).mean()) if (truth == lab).any() else float("nan")}
                     for lab in p.constraints[1:]}
    # (ours) which class each synthesized gesture was taken for, and from which turn
    confusion = {kind: {lab: {q: int(((np.array(gest[kind][0]) == lab) & (np.array(gest[kind][1]) == q)).sum())
                              for q in p.constraints} for lab in p.constraints[1:]} for kind in gest}
    predictions = {kind: [{"turn": n, "truth": a, "predicted": b} for a, b, n in zip(*gest[kind])]
                   for kind in gest}
    cm_j = np.array([r["cca_m"] for r in per_turn["jdbn"]])
    cm_c = np.array([r["cca_m"] for r in per_turn["cdbn"]])
    cms_j = np.array([r["cca_ms"] for r in per_turn["jdbn"]])
    cms_c = np.array([r["cca_ms"] for r in per_turn["cdbn"]])
    tests = {"cca_m_paired_t_p": float(stats.ttest_rel(cm_c, cm_j).pvalue),
             "cca_ms_paired_t_p": float(stats.ttest_rel(cms_c, cms_j).pvalue)}
    orig_ms = np.array([r["cca_orig_ms"] for r in per_turn["jdbn"]])
    return {"chosen_states": chosen, "validation_curves": curves, "table": table, "per_turn": per_turn,
            "gesture_accuracy": acc, "gesture_confusion": confusion, "gesture_predictions": predictions,
            "tests": tests, "cca_original_speech_motion": float(orig_ms.mean()),
            "fold1": folds_out, "test_folds": test_folds, "phase_seconds": phases}


def transition_distances(turns: list[Turn], p: CDBNParams, n: int, ep: CDBNEvalParams | None = None,
                         warm: TrainedModel | None = None) -> dict:
    """Eq. 8 between the nod and shake transition matrices: shared-state model (option 1 of Sec. VII-B)
    vs sparse CDBN (option 2), both trained with EM run to convergence (``ep.distance_max_iter``,
    ``ep.distance_tol``). Also reported (ours): the sparse distance over the rows of states both
    constraints own (``sparse_common_rows``: the rows of the other states are structural, a forced
    move into the shared state under one constraint), and each model's EM iteration count.
    ``warm``: a CDBN already trained on ``turns`` with N = ``n`` (the cross-validation's); with
    ``ep.distance_warm_start`` the sparse model continues EM from it to convergence."""
    ep = ep or CDBNEvalParams()
    names = p.constraints
    a, b = names.index("nod"), names.index("shake")
    tp = TrainParams(**{**p.train.__dict__, "max_iter": ep.distance_max_iter, "tol": ep.distance_tol})
    shared = fit("shared", turns, n, p, tp)
    if warm is not None and ep.distance_warm_start:
        if warm.kind != "cdbn" or warm.model.num_constraints != len(names):
            raise ValueError(f"warm start needs a CDBN over {names}, got a {warm.kind}")
        batch = make_batch([t.observations() for t in turns], [t.constraints for t in turns], pack=True)
        more = fit_em(warm.model, batch, tp)
        cd = TrainedModel(more.model, warm.owners, list(warm.log_likelihoods) + list(more.log_likelihoods), "cdbn",
                          warm.merges, warm.transition_mask, warm.initial_mask)
    else:
        cd = fit("cdbn", turns, n, p, tp)
    both = cd.owners[:, a] & cd.owners[:, b]
    ta, tb = cd.model.transitions[a], cd.model.transitions[b]
    return {"shared": transition_distance(shared.model.transitions[a], shared.model.transitions[b]),
            "sparse": transition_distance(ta, tb),
            "sparse_common_rows": transition_distance(ta[both], tb[both]) if both.any() else float("nan"),
            "states": n, "em_iterations": {"shared": len(shared.log_likelihoods), "cdbn": len(cd.log_likelihoods)},
            "max_iter": ep.distance_max_iter, "tol": ep.distance_tol,
            "warm_started": bool(warm is not None and ep.distance_warm_start)}


def init_comparison(turns: list[Turn], p: CDBNParams, n: int) -> dict:
    """Fig. 6: jDBN with n states after random vs LBG initialization (means, covariances of the motion
    stream, and the spread of the state means)."""
    out = {}
    for init in ("random", "lbg"):
        tm = fit("jdbn", turns, n, p, TrainParams(**{**p.train.__dict__, "init": init}))
        md = list(tm.model.motion_dims)
        mu = tm.model.means[:, md]
        out[init] = {"motion_means": mu, "motion_covariances": tm.model.covariances[:, md][:, :, md],
                     "mean_spread": float(np.mean(np.linalg.norm(mu - mu.mean(0), axis=1))),
                     "loglik_per_frame": float(tm.log_likelihoods[-1])}
    return out
