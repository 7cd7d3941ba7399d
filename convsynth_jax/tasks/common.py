"""Helpers shared by tasks: the compilation cache switch and graph files as models; the configured
corpus, its cached annotation and the configured system come from :mod:`convsynth_jax.api`."""
from __future__ import annotations

import logging
from pathlib import Path

from ..api import (annotated_corpus, cache_dir, make_configured_system, open_corpus,  # noqa: F401  (the tasks' names)
                   pairing_note, params_of)
from ..errors import ConfigError

log = logging.getLogger(__name__)


def enable_compilation_cache(cfg) -> Path | None:
    """:func:`convsynth_jax.kernel_cache.enable_compilation_cache` with the config's ``jax_cache`` group
    (off when the config has none)."""
    from .. import kernel_cache
    from ..config import group_params

    return kernel_cache.enable_compilation_cache(group_params(cfg, "jax_cache") if cfg.get("jax_cache") is not None
                                                 else None)


def graph_file_models(given, ann, system):
    """Motion-graph models from graph files (``task.graphs.<character>=FILE``: task=synthesize and
    task=converse), each clip checked against the configured corpus's recordings."""
    from ..graph import load_graph
    from ..systems.motion_graph import MotionGraphSystem

    if not isinstance(system, MotionGraphSystem):
        raise ConfigError(f"task.graphs gives motion graphs: it needs system=motion_graph (got {system.name!r})")
    out = {}
    for char, path in given.items():
        g = load_graph(path)
        motions, labels = {}, {}
        for cn in g.clip_names:
            s_name, role = cn.rsplit("_", 1)
            if s_name not in ann or role not in ann[s_name]:
                raise ConfigError(f"graph {path}: clip {cn!r} is not a recording of the configured corpus")
            a = ann[s_name][role]
            motions[cn], labels[cn] = a.motion, (a.own, a.partner)
        out[char] = system.graph_model(g, motions, 0.0, labels)   # with the configured penalties
    system.prepare(out)
    return out
