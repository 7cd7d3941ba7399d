"""Tasks of the ``convsynth`` Hydra app: one module per task, each with ``run(cfg, out_dir) -> dict``.

Task modules take an omegaconf ``DictConfig`` and a directory; they never import hydra.
"""
