"""Writing the corpus: every session's BVH, WAV and transcript files, ``events.csv``,
``glitches.csv`` and ``corpus.json`` (atomically), and the cache lookup ``ensure_synthetic_corpus``
(safe for several processes sharing one cache folder: the corpus is generated once, under a lock, into
a temporary folder renamed into place when complete)."""
from __future__ import annotations

import functools
import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from ...io.audio import save_wav
from ...io.bvh import save_bvh
from ...io.transcripts import save_transcript_tsv
from ...parallel import ordered_map
from ...utils import _umask, file_lock, replace_dir, write_error
from .calibration import planting_probabilities
from .config import GENERATOR_VERSION, ROLES, config_hash, resolve_config
from .plan import _plan, _quota_offsets, _render_motion, _render_rng
from .voice import _render_voice

log = logging.getLogger(__name__)


def _session(idx: int, cfg: dict, probs: dict, offsets: list[dict], out: Path) -> tuple[list[dict], list[dict], dict]:
    plan = _plan(idx, cfg, probs, offsets)
    name, duration, segs = plan["name"], plan["duration"], plan["segs"]
    sr = int(cfg["sample_rate"])
    rows, glitch_rows = [], []
    for role in ROLES:
        ch = cfg["characters"][role]
        own = [s for s in segs if s.role == role]
        events = plan["events"][role]
        motion, gl = _render_motion(plan, role, cfg)
        glitch_rows += [{"session": name, "participant": role, **g} for g in gl]
        save_bvh(motion, out / f"{name}_{role}.bvh", precision=4)
        words = [(w[0], w[1], w[2]) for s in own for w in s.words]
        save_transcript_tsv(pd.DataFrame(words, columns=["start", "end", "word"]), out / f"{name}_{role}.tsv")
        if cfg["write_audio"]:
            sig, _ = _render_voice(own, ch["f0"], duration, sr, _render_rng(cfg, idx, role, "audio"),
                                   cfg["accent_rise"])
            save_wav(out / f"{name}_{role}.wav", sig, sr)
        for s in own:
            rows.append({"session": name, "participant": role, "kind": s.kind, "start": s.start, "peak": s.peak,
                         "end": s.end, "text": " ".join(w[2] for w in s.words), "source": "", "cause_start": np.nan})
        for e in events:
            rows.append({"session": name, "participant": role, "kind": e["kind"], "start": e["start"],
                         "peak": e["peak"], "end": e["end"], "text": "", "source": e["source"],
                         "cause_start": e.get("cause_start", np.nan)})
    return rows, glitch_rows, {"name": name, "emotion": plan["emotion"], "duration": duration,
                               "spontaneous_free_seconds": {r: round(v, 4) for r, v in plan["free_seconds"].items()}}


GLITCH_COLUMNS = ["session", "participant", "kind", "joint", "channel", "degrees", "start_frame", "end_frame"]


def make_synthetic_corpus(out_dir: str | Path, config=None, workers: int | None = None) -> Path:
    """Write the synthetic corpus into ``out_dir`` (replaced atomically). Same seed, same bytes, for
    any number of ``workers`` (processes, one session each at a time; ``convsynth_jax.parallel``)."""
    cfg = resolve_config(config)
    out_dir = Path(out_dir)
    try:
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    except OSError as e:
        raise write_error(e, out_dir) from None
    try:
        probs, calibration = planting_probabilities(cfg)
        offsets = _quota_offsets(cfg)
        rows, glitches, sessions = [], [], []
        session = functools.partial(_session, cfg=cfg, probs=probs, offsets=offsets, out=tmp)
        for r, g, meta in ordered_map(session, range(int(cfg["num_sessions"])), workers):
            rows += r
            glitches += g
            sessions.append(meta)
        ev = pd.DataFrame(rows).round({"start": 4, "peak": 4, "end": 4, "cause_start": 4})
        ev.to_csv(tmp / "events.csv", index=False, float_format="%.4f")
        gl = pd.DataFrame(glitches, columns=GLITCH_COLUMNS)
        gl.to_csv(tmp / "glitches.csv", index=False, float_format="%.4f")
        meta = {"generator": "convsynth_jax.data.synthetic", "generator_version": GENERATOR_VERSION,
                "seed": int(cfg["seed"]), "config": cfg, "config_hash": config_hash(cfg),
                "characters": {r: cfg["characters"][r]["name"] for r in ROLES}, "sessions": sessions,
                "calibration": calibration}
        (tmp / "corpus.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())
        replace_dir(tmp, out_dir)
    except BaseException as e:
        shutil.rmtree(tmp, ignore_errors=True)  # nothing half-written stays visible
        if isinstance(e, OSError) and write_error(e, out_dir) is not e:
            raise write_error(e, out_dir) from None
        raise
    log.info("wrote synthetic corpus %s (%d sessions)", out_dir, len(sessions))
    return out_dir


def _is_current(root: Path, cfg: dict) -> bool:
    """Whether ``root`` holds a complete corpus generated with ``cfg`` (``corpus.json`` is written last,
    inside the temporary folder, so its presence means the folder is complete)."""
    meta = root / "corpus.json"
    if not meta.is_file():
        return False
    try:
        return json.loads(meta.read_text()).get("config_hash") == config_hash(cfg)
    except (json.JSONDecodeError, OSError, AttributeError):
        return False


def ensure_synthetic_corpus(corpus_cfg, cache_dir) -> Path:
    """The synthetic corpus of ``corpus_cfg``: reuse it if present with the same parameters, else
    generate it. Location: ``corpus_cfg.root`` or ``<cache_dir>/<corpus_cfg.name>``. Processes started
    together on one cache folder generate it once: the first takes the folder's lock
    (``.<name>.lock`` beside it) and generates; the others wait, then find it complete."""
    root = corpus_cfg.get("root") if hasattr(corpus_cfg, "get") else None
    root = Path(root) if root else Path(cache_dir) / str(corpus_cfg.get("name", "synthetic_default"))
    cfg = resolve_config(corpus_cfg.get("generator"))
    if _is_current(root, cfg):
        return root
    with file_lock(root):
        if _is_current(root, cfg):  # generated by another process while this one waited
            return root
        if (root / "corpus.json").is_file():
            log.info("synthetic corpus at %s has other parameters: regenerating", root)
        else:
            log.info("generating synthetic corpus into %s", root)
        return make_synthetic_corpus(root, cfg)
