"""The synthetic dyadic conversation corpus (the embedded default dataset)."""
from .synthetic import DEFAULTS, ensure_synthetic_corpus, make_synthetic_corpus, resolve_config  # noqa: F401
