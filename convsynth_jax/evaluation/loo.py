"""Leave-one-out evaluation (paper Section 8): hold out one session, build each character's motion
graph from the other sessions, slide 15 s windows with a 14 s hop over the held-out audio and
synthesize both characters in each window, under one ablation condition.

Conditions (a sweep axis): ``all`` (PC + LR + HP constraints), ``no_lr``, ``no_hp``, ``none``
(no audio constraint: graph quality only).
"""
from __future__ import annotations

import hashlib
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from ..errors import ConfigError
from .windows import Window, sliding_windows, window_segments

log = logging.getLogger(__name__)

CONDITIONS = {
    "all": {"use_constraints": True, "use_lr": True, "use_hp": True},
    "no_lr": {"use_constraints": True, "use_lr": False, "use_hp": True},
    "no_hp": {"use_constraints": True, "use_lr": True, "use_hp": False},
    "none": {"use_constraints": False, "use_lr": False, "use_hp": False},
}


def condition_config(cfg: DictConfig, condition: str) -> DictConfig:
    """A copy of ``cfg`` whose ``search`` switches implement the ablation ``condition``."""
    if condition not in CONDITIONS:
        raise ConfigError(f"unknown condition {condition!r}; expected one of {sorted(CONDITIONS)}")
    c = OmegaConf.create(OmegaConf.to_container(cfg, resolve=False))
    OmegaConf.set_struct(c, False)
    for k, v in CONDITIONS[condition].items():
        c.search[k] = v
    return c


def config_hash(*parts) -> str:
    text = json.dumps([OmegaConf.to_container(p, resolve=True) if isinstance(p, DictConfig) else p
                       for p in parts], sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


@dataclass
class FoldGraphs:
    """Per character: the motion graph, the clip motions it indexes, and construction seconds."""

    graphs: dict = field(default_factory=dict)
    motions: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    summaries: dict = field(default_factory=dict)
