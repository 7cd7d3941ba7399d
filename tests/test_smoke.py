
from convsynth_jax.config import compose


def test_config_composes():
    cfg = compose(["task=inspect"])
    assert cfg.task.name == "inspect"
    assert cfg.features.fps == 30
