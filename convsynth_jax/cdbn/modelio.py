"""Model files: ``model_<kind>.npz`` with keys means (K, D), covariances (K, D, D), initial (C, K),
transitions (C, K, K), speech_dims, motion_dims, constraint_names, feature_layout, and optionally
the per-subject normalizations (speech_mean/sd, motion_mean/sd) and the rest pose. Written
atomically; loading checks the feature layout."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import CDBNError
from ..utils import atomic_path
from .params import DBNModel


def save_model(path: str | Path, model: DBNModel, **extra) -> Path:
    arrays = {"means": np.asarray(model.means, np.float64), "covariances": np.asarray(model.covariances, np.float64),
              "initial": np.asarray(model.initial, np.float64), "transitions": np.asarray(model.transitions, np.float64),
              "speech_dims": np.asarray(model.speech_dims, np.int64), "motion_dims": np.asarray(model.motion_dims, np.int64),
              "constraint_names": np.asarray(model.constraint_names, dtype=str),
              "feature_layout": np.asarray(model.feature_layout, dtype=str)}
    arrays.update({k: np.asarray(v) for k, v in extra.items() if v is not None})
    with atomic_path(path, suffix=".npz") as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    return Path(path)


def load_model(path: str | Path, expected_layout: tuple | None = None) -> tuple[DBNModel, dict]:
    """(model, extra arrays). CDBNError when the file is missing, malformed, or was trained on
    another feature layout than ``expected_layout``."""
    path = Path(path)
    if not path.is_file():
        raise CDBNError("model file not found", path)
    try:
        z = dict(np.load(path, allow_pickle=False))
    except (OSError, ValueError) as e:
        raise CDBNError(f"not a CDBN model file ({e})", path) from None
    need = ("means", "covariances", "initial", "transitions", "speech_dims", "motion_dims", "constraint_names")
    missing = [k for k in need if k not in z]
    if missing:
        raise CDBNError(f"model file lacks keys {missing}", path)
    layout = tuple(str(s) for s in z.get("feature_layout", np.array([], str)))
    if expected_layout is not None and layout != tuple(expected_layout):
        raise CDBNError(f"model was trained on feature layout {list(layout)} but the features here are "
                        f"{list(expected_layout)}; retrain the model for this feature layout", path)
    K, D = z["means"].shape
    if z["covariances"].shape != (K, D, D) or z["transitions"].shape[1:] != (K, K) or z["initial"].shape[1] != K:
        raise CDBNError(f"inconsistent shapes: means {z['means'].shape}, covariances {z['covariances'].shape}, "
                        f"initial {z['initial'].shape}, transitions {z['transitions'].shape}", path)
    model = DBNModel(z["means"], z["covariances"], z["initial"], z["transitions"],
                     tuple(int(i) for i in z["speech_dims"]), tuple(int(i) for i in z["motion_dims"]),
                     tuple(str(s) for s in z["constraint_names"]), layout)
    extra = {k: v for k, v in z.items() if k not in need and k != "feature_layout"}
    return model, extra
