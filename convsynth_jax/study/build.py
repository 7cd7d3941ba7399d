"""A study folder from a corpus and a synthesis system (paper Section 8.1).

Segments are leave-one-out test windows solved in every compared condition: the held-out sessions
are visited in a seeded order, their windows in a seeded order, and each window is synthesized for
both characters in every condition the pairs name (seeds as :func:`convsynth_jax.evaluation.loo.run_fold`
draws them, so a window solved in a sweep is solved here too); a window that fails in any condition
is skipped. ``sweep_cases`` (the ``cases.csv`` rows of a finished sweep) restricts the candidates to
windows the sweep solved in every condition. Each (segment, pair) becomes one side-by-side video
(:mod:`convsynth_jax.render`) with the window's audio (both participants mixed to mono), plus attention checks.

Output (``out_dir``): ``media/<id>.mp4``, ``audio/seg<k>.wav``, ``manifest.json`` (the study's
settings and one record per stimulus) and ``manifest.csv`` (the records). The manifest is written
last: a folder without one is an unfinished build.
"""
from __future__ import annotations

import hashlib
import json
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..seeding import derive_seed
from ..utils import atomic_path, write_json_atomic
from . import design
from ..render import PanelRenderer, body_from_motion, frozen, join_panels, write_video

log = logging.getLogger(__name__)

MANIFEST_COLUMNS = ("id", "kind", "pair", "segment", "session", "fold", "window", "window_start", "window_end",
                    "left", "right", "condition_a", "condition_b", "label_a", "label_b", "expected", "seeds", "file",
                    "sha256", "bytes")


def sha256_of(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def solved_in_sweep(cases: pd.DataFrame, conditions) -> set:
    """(session, window) pairs whose every row (both characters) succeeded in every condition."""
    need = {"session", "window", "condition", "success"}
    if not need <= set(cases.columns):
        raise ConfigError(f"sweep cases need columns {sorted(need)}, have {sorted(cases.columns)}")
    c = cases[cases["condition"].isin(list(conditions))].copy()
    c["success"] = c["success"].fillna(False).astype(bool)
    g = c.groupby(["session", "window"])
    ok = g["success"].all() & (g["condition"].nunique() == len(set(conditions)))
    return {(str(s), int(w)) for (s, w), v in ok.items() if v}


def _window_audio(held: dict, w, out: Path) -> Path | None:
    """Both participants' audio in window ``w`` mixed to mono (``out``), or None without audio."""
    from ..io import load_audio, save_wav

    parts, rate = [], None
    for ann in held.values():
        if not getattr(ann, "audio_path", None):
            return None
        a = load_audio(ann.audio_path, channel=ann.audio_channel)
        if a.samples.ndim > 1:
            a = a.channel(0)
        rate = a.sample_rate if rate is None else rate
        if a.sample_rate != rate:
            return None
        parts.append(np.asarray(a.samples[int(round(w.start * rate)):int(round(w.end * rate))], np.float64))
    n = max(len(p) for p in parts)
    mix = np.zeros(n)
    for p in parts:
        mix[:len(p)] += p
    return save_wav(out, np.clip(mix, -1.0, 1.0), rate)


def find_segments(system, annotations: dict, params, conditions, n: int, seed: int, folds=None, sweep_ok: set | None = None,
                  cache_dir=None, max_tries: int | None = None) -> tuple[list[dict], list[dict]]:
    """(segments, rejected): up to ``n`` windows solved for both characters in every condition, and
    the windows tried and skipped (with the condition and character that failed). Each segment:
    segment, session, fold, window, window_start, window_end, seeds, motions {condition: [role motions]}."""
    from ..evaluation.loo import fit_fold, session_windows, window_input

    names = list(annotations)
    folds = list(range(len(names))) if folds is None else [int(f) for f in folds]
    for f in folds:
        if not 0 <= f < len(names):
            raise ConfigError(f"fold {f} out of range: the corpus has {len(names)} sessions", where="task.folds")
    for c in conditions:
        system.condition_options(c)
    rng = np.random.default_rng([int(seed), 5])
    fps = float(params.features.fps)
    segments, rejected, tries = [], [], 0
    for fold in [folds[i] for i in rng.permutation(len(folds))]:
        held_out = names[fold]
        held = annotations[held_out]
        windows = session_windows(held, fps, params.loo.window, params.loo.hop, params.loo.max_windows)
        if sweep_ok is not None:
            windows = [w for w in windows if (held_out, w.index) in sweep_ok]
        if not windows:
            continue
        models: dict = {}
        fitted = {}
        for w in [windows[i] for i in rng.permutation(len(windows))]:
            if len(segments) >= n or (max_tries is not None and tries >= max_tries):
                return segments, rejected
            tries += 1
            f0 = int(round(w.start * fps))
            motions, seeds, failed = {}, {}, None
            for cond in conditions:
                if cond not in fitted:
                    fitted[cond] = fit_fold(system, annotations, held_out, cond, cache_dir, models)
                per_role = []
                for k, (role, ann) in enumerate(held.items()):
                    s = derive_seed(params.seed, fold=fold, condition=cond, session=held_out, window_frame=f0, role_index=k)
                    seeds[f"{cond}/{role}"] = s
                    win = window_input(held, role, w, fps, s, with_audio=system.needs_audio)
                    res = system.synthesize(fitted[cond][ann.character], win, cond)
                    if not res.success or res.motion is None:
                        failed = {"condition": cond, "role": role, "failure": res.failure}
                        break
                    per_role.append(res.motion)
                if failed:
                    break
                motions[cond] = per_role
            if failed:
                rejected.append({"session": held_out, "fold": fold, "window": w.index, **failed})
                log.info("window %s/%d skipped: %s", held_out, w.index, failed)
                continue
            nf = min(m.num_frames for ms in motions.values() for m in ms) if motions else int(round(w.duration * fps))
            motions[design.GROUND_TRUTH] = [ann.motion.slice(f0, f0 + nf) for ann in held.values()]
            segments.append({"segment": len(segments), "session": held_out, "fold": fold, "window": w.index,
                             "window_start": w.start, "window_end": w.end, "seeds": seeds, "motions": motions,
                             "_held": held, "_window": w})
            log.info("segment %d: %s window %d (%.0f-%.0f s)", len(segments) - 1, held_out, w.index, w.start, w.end)
    return segments, rejected


def build_study(system, annotations: dict, params, out_dir: str | Path, *, pairs, segments: int, attention: int,
                seed: int, folds=None, sweep_cases: pd.DataFrame | None = None, cache_dir=None, width: int = 320,
                height: int = 360, render_fps: float = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0,
                settings: dict | None = None) -> dict:
    """Build the study folder (see the module docstring); returns the manifest dict."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    if (out / "manifest.json").exists():
        raise ConfigError("the folder already holds a built study (and perhaps its answers); choose another task.out",
                          out, "manifest.json")
    conds = design.conditions_needed(pairs)
    sweep_ok = solved_in_sweep(sweep_cases, conds) if sweep_cases is not None else None
    segs, rejected = find_segments(system, annotations, params, conds, segments, seed, folds, sweep_ok, cache_dir)
    t_synth = time.perf_counter() - t0
    if len(segs) < segments:
        raise ConfigError(f"only {len(segs)} of {segments} segments are solved in every condition {conds} "
                          f"({len(rejected)} windows tried failed); lower task.segments or widen task.folds",
                          where="task.segments")
    fps = float(params.features.fps)
    plain = [{k: v for k, v in s.items() if k not in ("motions", "_held", "_window")} for s in segs]
    stimuli = design.plan_stimuli(plain, pairs, attention, seed)
    audio = {s["segment"]: _window_audio(s["_held"], s["_window"], out / "audio" / f"seg{s['segment']:02d}.wav") for s in segs}
    if any(a is None for a in audio.values()):
        log.warning("the corpus has no usable audio for some windows: their videos are silent")
    bodies: dict = {}

    def bodies_of(seg: int, cond: str):
        if (seg, cond) not in bodies:
            if cond == design.FROZEN:
                bodies[(seg, cond)] = [frozen(b) for b in bodies_of(seg, design.GROUND_TRUTH)]
            else:
                bodies[(seg, cond)] = [body_from_motion(m) for m in segs[seg]["motions"][cond]]
        return bodies[(seg, cond)]

    t1 = time.perf_counter()
    step = max(1, int(round(fps / render_fps)))
    done = {}
    for seg in range(len(segs)):
        # one camera per segment; each condition's panels drawn once and reused by every pair showing it
        mine = [s for s in stimuli if s["segment"] == seg]
        conds = sorted({c for s in mine for c in (s["left"], s["right"])})
        if not mine:
            continue
        panel = PanelRenderer([bodies_of(seg, c) for c in conds], width, height, step, yaw_deg, pitch_deg)
        frames: dict = {}
        for k, s in enumerate(mine):
            for c in (s["left"], s["right"]):
                if c not in frames:
                    frames[c] = panel.frames(bodies_of(seg, c))
            rel = f"media/{s['id']}.mp4"
            path = write_video(join_panels(frames[s["left"]], frames[s["right"]]), fps / step, out / rel, audio[seg])
            done[s["id"]] = {**{k2: s.get(k2) for k2 in MANIFEST_COLUMNS if k2 in s}, "file": rel, "sha256": sha256_of(path),
                             "bytes": path.stat().st_size}
            later = {c for x in mine[k + 1:] for c in (x["left"], x["right"])}
            for c in [c for c in frames if c not in later]:
                del frames[c]                                   # memory: only what later stimuli need
            log.info("stimulus %s: %s | %s (%s)", s["id"], s["left"], s["right"], s["pair"])
    records = [done[s["id"]] for s in stimuli]
    t_render = time.perf_counter() - t1
    manifest = {
        "study": {**(settings or {}), "seed": int(seed), "system": system.name, "fps": fps,
                  "pairs": [vars(p) for p in pairs], "segments": segments, "attention_stimuli": attention,
                  "video": {"panel_width": width, "panel_height": height, "render_fps": render_fps, "yaw_deg": yaw_deg,
                            "pitch_deg": pitch_deg, "codec": "h264+aac"}},
        "stimuli": records,
        "rejected_windows": rejected,
        "timings": {"synthesis_s": t_synth, "render_s": t_render, "total_s": time.perf_counter() - t0},
    }
    table = pd.DataFrame([{k: (json.dumps(r.get(k), sort_keys=True) if k == "seeds" else r.get(k)) for k in MANIFEST_COLUMNS}
                          for r in records])
    with atomic_path(out / "manifest.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_json_atomic(out / "manifest.json", manifest)
    return manifest


def load_study_manifest(study_dir: str | Path) -> dict:
    """The manifest of a built study folder; MissingFileError / FormatError name the file."""
    from ..errors import FormatError, MissingFileError

    p = Path(study_dir) / "manifest.json"
    if not p.is_file():
        raise MissingFileError("no study manifest (run task=study_build first)", p)
    try:
        m = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise FormatError(f"not a JSON manifest ({e})", p) from None
    if not isinstance(m, dict) or not isinstance(m.get("stimuli"), list) or "study" not in m:
        raise FormatError("manifest needs 'study' and a 'stimuli' list", p)
    for i, s in enumerate(m["stimuli"]):
        missing = {"id", "kind", "left", "right", "file", "pair"} - set(s)
        if missing:
            raise FormatError(f"stimulus record lacks {sorted(missing)}", p, f"stimuli[{i}]")
    return m
