"""pytest plugin of bench_test_suite.py: each XLA compilation in this pytest process (the controller or an
xdist worker) as (test node id, jitted function, seconds), from JAX's
``/jax/core/compile/backend_compile_duration`` event, written as JSON into ``$COMPILE_LISTENER_OUT`` when
the process ends. Compilations in processes the tests start themselves are not seen."""
import json
import os
from pathlib import Path

EVENT = "/jax/core/compile/backend_compile_duration"
_test = ["<collection>"]
_rows = []


def _listen(event, seconds, **kwargs):
    if event == EVENT:
        _rows.append((_test[0], str(kwargs.get("fun_name", "?")), float(seconds)))


def pytest_configure(config):
    import jax.monitoring

    jax.monitoring.register_event_duration_secs_listener(_listen)


def pytest_runtest_setup(item):
    _test[0] = item.nodeid


def pytest_unconfigure(config):
    out = Path(os.environ["COMPILE_LISTENER_OUT"])
    name = os.environ.get("PYTEST_XDIST_WORKER", "controller")
    (out / f"{name}.json").write_text(json.dumps(_rows))
