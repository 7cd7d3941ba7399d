"""Every system scored with the field's metrics on the same leave-one-out windows (docs/metrics.md).

The windows are those of leave-one-out (:mod:`.loo`: 15 s windows with a 14 s hop over each held-out
session, both characters). Beside the configured systems, two controls come from the recordings:
``ground_truth`` (the window's own motion) and ``mismatched_ground_truth`` (the field's standard
control: the same role's recorded motion of the same-numbered window of the next session, under
this window's audio). A system's motion comes from a finished leave-one-out sweep (the BVH files
that ``task=loo task.export_bvh=true`` writes beside ``cases.csv``) or from running its folds here
with :func:`.loo.run_fold`. A window a system failed, or that a sweep lacks, is a row with its
status and error and no metrics, never a crash.

Every system is scored in the ``head`` scope (the head point); those that animate hands (and the
two controls) also in the ``body`` scope (:mod:`.field.views`). The metrics are those of
:mod:`.field`; the leaderboard gives each (system, scope) the mean of each per-window metric and
each set-level metric, a bootstrap 95% interval over sessions, and a rank.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from ..utils import show_progress_bar

from ..errors import ConfigError
from .field import score
from .field.autoencoder import TrainedAutoencoder, train_autoencoder
from .field.beat import audio_beats
from .field.cca import speech_cca_features
from .field.coverage import covered_cells
from .field.params import FieldMetricParams
from .field.views import SCOPES, motion_view
from .windows import Window

log = logging.getLogger(__name__)

GROUND_TRUTH = "ground_truth"
MISMATCHED = "mismatched_ground_truth"
# not a system: the set-level metrics of the ground truth's odd windows against its even windows (each
# metric's noise floor at half the windows); it has no per-window metrics
NOISE_FLOOR = "ground_truth_odd_vs_even"


@dataclass(frozen=True)
class Case:
    """One evaluated window of one character (the unit of a ``benchmark.csv`` row)."""

    fold: int
    session: str
    window: int
    start: float
    end: float
    role: str
    character: str
    start_frame: int
    num_frames: int

    @property
    def key(self) -> tuple:
        return (self.fold, self.window, self.role)


@dataclass
class SystemMotions:
    """One system's motion per case key: (status, error, Motion or None); scopes it is scored in."""

    name: str
    scopes: tuple
    motions: Dict[tuple, tuple] = field(default_factory=dict)
    source: str = ""


def benchmark_cases(annotations: dict, fps: float, window: float, hop: float, max_windows: Optional[int] = None,
                    folds: Optional[List[int]] = None) -> List[Case]:
    """The leave-one-out cases of the given folds (default: all); ConfigError with fewer than two
    sessions (leave-one-out's own condition) or a fold out of range."""
    from .loo import session_windows

    names = list(annotations)
    if len(names) < 2:
        raise ConfigError(f"leave-one-out needs at least two sessions; the corpus has {len(names)}")
    folds = list(range(len(names))) if folds is None else list(folds)
    bad = [f for f in folds if not 0 <= f < len(names)]
    if bad:
        raise ConfigError(f"fold {bad[0]} out of range: the corpus has {len(names)} sessions")
    out = []
    for f in folds:
        held = annotations[names[f]]
        for w in session_windows(held, fps, window, hop, max_windows):
            for role, ann in held.items():
                out.append(Case(f, names[f], w.index, w.start, w.end, role, ann.character,
                                int(round(w.start * fps)), int(round(w.duration * fps))))
    return out


def mismatched_source(annotations: dict, case: Case, fps: float, window: float, hop: float) -> tuple[str, int]:
    """(session, start frame) of the mismatched ground truth of ``case``: the same role in the next
    session (cyclically), window number ``case.window`` modulo that session's windows."""
    from .loo import session_windows

    names = list(annotations)
    other = names[(case.fold + 1) % len(names)]
    ws = session_windows(annotations[other], fps, window, hop)
    if not ws:
        raise ConfigError(f"session {other!r} is shorter than one {window} s window")
    w = ws[case.window % len(ws)]
    return other, int(round(w.start * fps))


def case_audio(annotations: dict, case: Case, fps: float):
    """The character's own audio over the case's window (None when the corpus has no audio)."""
    from .loo import window_input

    held = annotations[case.session]
    win = window_input(held, case.role, Window(case.window, case.start, case.end), fps, 0, with_audio=True)
    return win.own_audio


def controls(annotations: dict, cases: List[Case], fps: float, window: float, hop: float) -> tuple[SystemMotions, SystemMotions]:
    """The ground truth and the mismatched ground truth as systems."""
    gt = SystemMotions(GROUND_TRUTH, SCOPES, source="recordings")
    mm = SystemMotions(MISMATCHED, SCOPES, source="recordings (next session, same role)")
    for c in cases:
        m = annotations[c.session][c.role].motion
        gt.motions[c.key] = ("ok", "", m.slice(c.start_frame, c.start_frame + c.num_frames))
        other, f0 = mismatched_source(annotations, c, fps, window, hop)
        mo = annotations[other][c.role].motion
        piece = mo.slice(f0, f0 + c.num_frames)
        if piece.num_frames < c.num_frames:
            mm.motions[c.key] = ("failed", f"{other} has only {piece.num_frames} frames from {f0}", None)
        else:
            mm.motions[c.key] = ("ok", "", piece)
    return gt, mm


def sweep_motions(root: str | Path, name: str, condition: str, cases: List[Case], scopes: tuple) -> SystemMotions:
    """A system's motion read from a finished leave-one-out sweep below ``root`` (``cases.csv`` and
    ``bvh/<session>_w<window>_<character>_<condition>.bvh`` per job, as ``task=loo
    task.export_bvh=true`` writes them). Cases the sweep failed or lacks get that status."""
    from ..io import load_bvh
    from .collect import collect_cases

    root = Path(root)
    table = collect_cases(root)
    out = SystemMotions(name, scopes, source=str(root))
    if "condition" in table:
        table = table[table["condition"].astype(str) == str(condition)]
    index = {}
    for r in table.to_dict("records"):
        if pd.notna(r.get("window")) and pd.notna(r.get("fold")):
            index[(int(r["fold"]), int(r["window"]), str(r.get("role")))] = r
    failed_jobs = {int(r["fold"]): str(r.get("error")) for r in table.to_dict("records")
                   if pd.isna(r.get("window")) and pd.notna(r.get("fold"))}
    for c in cases:
        r = index.get(c.key)
        if r is None:
            err = failed_jobs.get(c.fold, f"no row for fold {c.fold} window {c.window} {c.role} in {root}")
            out.motions[c.key] = ("missing" if c.fold not in failed_jobs else "error", err, None)
            continue
        if not bool(r.get("success")) or str(r.get("status", "ok")) == "error":
            out.motions[c.key] = ("failed", str(r.get("error") or r.get("failure") or "unsuccessful"), None)
            continue
        path = root / str(r.get("job_dir", ".")) / "bvh" / f"{c.session}_w{c.window:02d}_{c.character}_{condition}.bvh"
        if not path.is_file():
            out.motions[c.key] = ("missing", f"no BVH {path} (run the sweep with task.export_bvh=true)", None)
            continue
        try:
            m = load_bvh(path)
        except Exception as e:  # a broken file is a recorded failure of that window
            out.motions[c.key] = ("error", f"{type(e).__name__}: {e}", None)
            continue
        out.motions[c.key] = ("ok", "", m.slice(0, c.num_frames))
    return out


def run_system(system, annotations: dict, cases: List[Case], condition: str, params, out_root: Path,
               cache_dir=None) -> SystemMotions:
    """Run the folds ``cases`` need with leave-one-out (BVH exported into ``out_root/<fold>``) and
    read them back; a fold that raises is recorded for its windows."""
    from ..utils import atomic_path
    from .loo import recording_threshold_table, run_fold

    out_root = Path(out_root)
    table = recording_threshold_table(annotations, params.annotate)
    models: dict = {}
    for fold in sorted({c.fold for c in cases}):
        job = out_root / f"{fold}"
        job.mkdir(parents=True, exist_ok=True)
        try:
            df = run_fold(system, annotations, fold, condition, params, out_dir=job, cache_dir=cache_dir,
                          export_bvh=True, models=models, with_audio=system.needs_audio, thresholds=table)
        except Exception as e:  # recorded, the benchmark goes on
            log.exception("%s fold %d failed", system.name, fold)
            df = pd.DataFrame([{"system": system.name, "fold": fold, "condition": condition, "status": "error",
                                "success": False, "error": f"{type(e).__name__}: {e}"}])
        models.clear()
        with atomic_path(job / "cases.csv") as tmp:
            df.to_csv(tmp, index=False)
    scopes = SCOPES if system.produces_hands else ("head",)
    return sweep_motions(out_root, system.name, condition, cases, scopes)


@dataclass
class BenchmarkResult:
    rows: pd.DataFrame           # one row per case x system x scope
    leaderboard: pd.DataFrame    # one row per system x scope x metric
    autoencoders: Dict[tuple, TrainedAutoencoder]
    seconds: Dict[str, float]


def train_autoencoders(training: List[Any], params: FieldMetricParams, annotate_params, scopes, cache_dir=None
                       ) -> Dict[tuple, TrainedAutoencoder]:
    """(scope, window) -> autoencoder trained on the relative views of ``training`` (Motions)."""
    out = {}
    for scope in scopes:
        rel = [motion_view(m, scope, params.joints, annotate_params).relative for m in training]
        for w in params.autoencoder.window_frames:
            out[(scope, w)] = train_autoencoder(rel, w, params.autoencoder, cache_dir)
    return out


def score_benchmark(cases: List[Case], systems: List[SystemMotions], audio: Dict[tuple, Any], fps: float,
                    params: FieldMetricParams, annotate_params, autoencoders: Dict[tuple, TrainedAutoencoder],
                    progress: bool = False) -> BenchmarkResult:
    """Rows and leaderboard of ``systems`` (the first must be the ground truth) on ``cases``;
    ``audio``: case key -> the character's audio of the window (None: no beat consistency or
    speech CCA)."""
    t0 = time.perf_counter()
    gt_sys = systems[0]
    if gt_sys.name != GROUND_TRUTH:
        raise ValueError("the first system must be the ground truth")
    beats, speech = {}, {}
    for c in cases:
        a = audio.get(c.key)
        beats[c.key] = audio_beats(a, params.beat) if a is not None else None
        speech[c.key] = speech_cca_features(a, c.num_frames, fps, params.cca) if a is not None else None
    t_audio = time.perf_counter() - t0
    rows: List[dict] = []
    set_moments: Dict[tuple, score.SetMoments] = {}
    # (system, scope) -> (scope, the keys of the windows it scored), the ground truth's moments of them
    refs: Dict[tuple, Tuple[tuple, score.SetMoments]] = {}
    for scope in SCOPES:
        aes = {w: ae for (s, w), ae in autoencoders.items() if s == scope}
        gt_views = {c.key: (c.session, motion_view(gt_sys.motions[c.key][2], scope, params.joints, annotate_params))
                    for c in cases}
        by_keys: Dict[frozenset, score.SetMoments] = {}

        def reference(keys) -> score.SetMoments:
            keys = frozenset(keys)
            if keys not in by_keys:
                by_keys[keys] = score.reference_moments({k: v for k, v in gt_views.items() if k in keys},
                                                        params, aes, fps)
            return by_keys[keys]

        gt_cells = ({k: covered_cells(v.relative, v.parents, params.coverage) for k, (_, v) in gt_views.items()}
                    if scope == "body" else {})
        for sysm in systems:
            if scope not in sysm.scopes:
                continue
            mom = set_moments.setdefault((sysm.name, scope), score.SetMoments())
            encoded = []   # (session, relative) of the scored windows, encoded together below
            scored = []
            for c in tqdm(cases, desc=f"{sysm.name} {scope}", disable=not show_progress_bar(progress), leave=False):
                status, err, motion = sysm.motions.get(c.key, ("missing", "not run", None))
                base = {"system": sysm.name, "scope": scope, "fold": c.fold, "session": c.session, "window": c.window,
                        "window_start": c.start, "window_end": c.end, "character": c.character, "role": c.role,
                        "status": status, "error": err}
                if status == "ok":
                    try:
                        view = motion_view(motion, scope, params.joints, annotate_params)
                        m = score.score_window(view, gt_views[c.key][1], beats[c.key], speech[c.key], fps,
                                               c.num_frames / fps, params, scope, mom, c.session,
                                               gt_cells.get(c.key))
                        base.update(m)
                        encoded.append((c.session, view.relative))
                        scored.append(c.key)
                    except Exception as e:  # a window the metrics cannot read is recorded, not fatal
                        log.exception("%s %s: metrics failed", sysm.name, c)
                        base.update({"status": "error", "error": f"metrics: {type(e).__name__}: {e}"})
                rows.append(base)
            score.add_codes(mom, encoded, aes)
            # set-level metrics compare the system with the ground truth of the windows it scored, so
            # a system that fails some windows is neither helped nor hurt by which ones
            refs[(sysm.name, scope)] = ((scope, frozenset(scored)), reference(scored))
        odd = [c.key for c in cases if c.window % 2]
        even = [c.key for c in cases if not c.window % 2]
        if odd and even:
            set_moments[(NOISE_FLOOR, scope)] = reference(odd)
            refs[(NOISE_FLOOR, scope)] = ((scope, frozenset(even)), reference(even))
    df = pd.DataFrame(rows)
    # CCA: one fit per (system, scope) over all its windows, then each window's correlation
    for (name, scope), mom in set_moments.items():
        wts = score.cca_weights(mom, params.cca.ridge)
        sel = np.flatnonzero((df["system"] == name).to_numpy() & (df["scope"] == scope).to_numpy())
        for i in sel:
            pair = df.at[i, "_cca"] if "_cca" in df else None
            if isinstance(pair, tuple):
                for k, v in score.window_cca(pair, wts).items():
                    df.at[i, k] = v
    df = df.drop(columns=["_cca"], errors="ignore")
    for m in score.WINDOW_METRICS:
        if m not in df:
            df[m] = np.nan
    t_windows = time.perf_counter() - t0 - t_audio
    board = leaderboard(df, set_moments, refs, params)
    secs = {"audio_s": t_audio, "windows_s": t_windows, "leaderboard_s": time.perf_counter() - t0 - t_audio - t_windows}
    return BenchmarkResult(df, board, autoencoders, secs)


def leaderboard(rows: pd.DataFrame, set_moments: dict, refs: dict, params: FieldMetricParams) -> pd.DataFrame:
    """system x scope x metric: value, bootstrap 95% interval over sessions, rank within the scope
    (1 = best by :data:`.field.score.DIRECTION`; ``gt`` metrics rank by the distance to the ground
    truth's value), windows scored and failed. ``refs``: (system, scope) -> (a key naming the
    windows that system scored, the ground truth's set moments of them). The row :data:`NOISE_FLOOR` (set-level metrics of
    the ground truth's odd windows against its even ones) is shown without a rank."""
    out = []
    caches: Dict[tuple, dict] = {}   # reference Gaussians per resample, one per set of windows, shared by systems
    for (name, scope), mom in set_moments.items():
        ref_key, ref = refs[(name, scope)]
        cache = caches.setdefault(ref_key, {})
        sub = rows[(rows["system"] == name) & (rows["scope"] == scope)]
        ok = sub[sub["status"] == "ok"]
        sessions = sorted(rows["session"].unique())
        ones = {s: 1.0 for s in sessions}
        sums = score.window_sums(ok)
        floor = name == NOISE_FLOOR
        point = {**({} if floor else score.window_means(sums, ones)), **score.set_metrics(mom, ref, ones, params)}
        if floor:   # only what two sets of recordings can be compared by: no CCA against a paired stream
            point = {k: v for k, v in point.items() if not k.startswith("cca")}

        ci_w = ({} if floor else
                score.bootstrap_intervals(lambda w: score.window_means(sums, w), sessions, params.bootstrap, params.seed))
        ci_s = score.bootstrap_intervals(
            lambda w: score.set_metrics(mom, ref, w, params, fast=True, cache=cache), sessions,
            params.bootstrap_set_level, params.seed)
        ci = {**ci_w, **ci_s}
        n_ok = int(len(ok))
        if floor:   # the odd windows' count, from the rows of the ground truth in this scope
            gt = rows[(rows["system"] == GROUND_TRUTH) & (rows["scope"] == scope) & (rows["status"] == "ok")]
            n_ok = int((gt["window"] % 2 == 1).sum())
        for metric, v in point.items():
            lo, hi = ci.get(metric, (np.nan, np.nan))
            out.append({"system": name, "scope": scope, "metric": metric, "value": v, "ci_low": lo, "ci_high": hi,
                        "n_windows": n_ok, "n_failed": 0 if floor else int(len(sub) - len(ok))})
    board = pd.DataFrame(out)
    if board.empty:
        return board
    board["rank"] = np.nan
    ranked = board[board["system"] != NOISE_FLOOR]   # the noise floor is shown, not ranked
    for (scope, metric), g in ranked.groupby(["scope", "metric"]):
        direction = score.DIRECTION.get(metric, "low" if metric.startswith("fgd") else "high")
        v = g["value"].to_numpy(np.float64)
        if direction == "gt":
            ref = g.loc[g["system"] == GROUND_TRUTH, "value"]
            key = np.abs(v - (float(ref.iloc[0]) if len(ref) else np.nan))
        else:
            key = v if direction == "low" else -v
        # values equal to 6 significant digits (or both below 1e-8: round-off of a zero) tie
        key = np.where(np.abs(key) < 1e-8, 0.0, key)
        key = np.array([float(f"{k:.6g}") if np.isfinite(k) else np.nan for k in key])
        board.loc[g.index, "rank"] = pd.Series(key, index=g.index).rank(method="min", na_option="keep")
    return board


def leaderboard_markdown(board: pd.DataFrame, digits: int = 3) -> str:
    """One Markdown table per scope: systems as rows, metrics as columns, "value [low, high] (rank)"."""
    lines = []
    for scope, g in board.groupby("scope", sort=False):
        metrics = list(dict.fromkeys(g["metric"]))
        systems = list(dict.fromkeys(g["system"]))
        lines += [f"### scope: {scope}", "", "| system | " + " | ".join(metrics) + " |",
                  "|---|" + "---|" * len(metrics)]
        for s in systems:
            cells = []
            for m in metrics:
                r = g[(g["system"] == s) & (g["metric"] == m)]
                if r.empty or not np.isfinite(r["value"].iloc[0]):
                    cells.append("")
                    continue
                r = r.iloc[0]
                ci = f" [{r['ci_low']:.{digits}g}, {r['ci_high']:.{digits}g}]" if np.isfinite(r["ci_low"]) else ""
                rank = f" ({int(r['rank'])})" if np.isfinite(r["rank"]) else ""
                cells.append(f"{r['value']:.{digits}g}{ci}{rank}")
            lines.append(f"| {s} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines) + "\n"
