"""Task ``make_scale_db``: a large motion database for scaling benchmarks (graph/scale_db.py).

    convsynth task=make_scale_db frames=1000000 [task.bandai_root=DIR] [task.out=DIR] [task.seed=0]

Real Bandai clips from ``task.bandai_root`` (default: the shared data folder's ``bandai2/bvh`` when it
exists; synthetic motion only otherwise) and synthetic-corpus sessions, with seeded mirrored,
time-warped and noisy variants, exactly ``frames`` frames. Written as a memory-mappable array folder
(graph/store.py) to ``task.out`` (default ``<run dir>/scale_db``); ``summary.json`` gives the counts.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

# the shared data folder of this project's checkouts (data/README: bandai2/bvh)
DEFAULT_BANDAI = Path(__file__).resolve().parents[3] / "shared" / "data" / "bandai2" / "bvh"


@dataclass(frozen=True)
class MakeScaleDBSettings:
    """``conf/task/make_scale_db.yaml``."""

    name: str = "make_scale_db"
    frames: int = 1_000_000            # the top-level ``frames=`` wins when set
    seed: int = 0
    bandai_root: Optional[str] = None  # None: DEFAULT_BANDAI if it exists, else synthetic only
    out: Optional[str] = None          # None: <run dir>/scale_db
    calibrate: bool = True             # the synthetic corpus's planting-rate calibration


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..graph.scale_db import ScaleDBParams, make_scale_database
    from ..graph.store import save_database

    s = task_settings(cfg)
    frames = int(cfg.get("frames") or s.frames)
    root = s.bandai_root if s.bandai_root is not None else (str(DEFAULT_BANDAI) if DEFAULT_BANDAI.is_dir() else None)
    t0 = time.perf_counter()
    db = make_scale_database(ScaleDBParams(frames=frames, seed=s.seed, bandai_root=root, calibrate=s.calibrate))
    seconds = time.perf_counter() - t0
    out = Path(s.out) if s.out else out_dir / "scale_db"
    save_database(db, out)
    return {"database": str(out), "num_frames": db.num_frames, "num_clips": len(db.clip_names),
            "bandai_root": root, **db.meta["scale_db"], "seconds": seconds}
