"""One name per idea: no two public classes or functions of the package share a name (a name with
two meanings across packages reads as one idea). Task modules' ``run`` entry points are the one
exception by design; the remaining pairs are one idea at two levels (a task-level wrapper of the
library function, or the same conversion for two parameter groups)."""
import ast
from collections import defaultdict
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "convsynth_jax"
SAME_IDEA = {
    "enable_compilation_cache",   # tasks/common.py: the task-level switch over kernel_cache's
    "params_from_dict",           # a mapping -> that package's parameter dataclass (cdbn, walktalk)
}


def test_public_names_are_unique_across_the_package():
    homes = defaultdict(list)
    for path in sorted(PKG.rglob("*.py")):
        if "testing" in path.relative_to(PKG).parts:
            continue
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
                homes[node.name].append(str(path.relative_to(PKG)))
    clashes = {n: h for n, h in homes.items() if len(h) > 1 and n != "run" and n not in SAME_IDEA}
    assert clashes == {}


def test_no_library_module_is_named_like_a_test():
    assert [str(p.relative_to(PKG)) for p in PKG.rglob("test*.py")] == []


def test_experiments_use_the_public_api_not_the_tasks():
    """Scripts under experiments/ get the configured corpus, its annotation and system from
    ``convsynth_jax.api`` (what the tasks use too), not from ``convsynth_jax.tasks``."""
    exp = PKG.parent / "experiments"
    found = {str(p.relative_to(exp)) for p in exp.rglob("*.py") if "convsynth_jax.tasks" in p.read_text()}
    assert found == set(), sorted(found)


def test_experiments_do_not_edit_sys_path():
    """Scripts under experiments/ import the installed package (and siblings of their own folder, which
    Python puts on the path of a script it runs); none edits ``sys.path``."""
    exp = PKG.parent / "experiments"
    found = sorted(str(p.relative_to(exp)) for p in exp.rglob("*.py") if "sys.path" in p.read_text())
    assert found == []
