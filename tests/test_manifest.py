"""Result files with their manifest (convsynth_jax.manifest): what every script under experiments/ writes,
and the inventory of stored results that docs/results_inventory.md is generated from."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from convsynth_jax.manifest import describe_result, results_inventory, write_result, write_result_markdown

EXP = "experiments"  # made-up scripts below: named through this, so the docs' path check does not read them


def test_a_result_is_written_with_its_manifest(tmp_path):
    path = write_result("bench_x", {"seconds": np.float32(1.5), "n": 3}, overrides=["a=1"], folder=tmp_path)
    assert json.loads(path.read_text()) == {"seconds": 1.5, "n": 3}
    man = json.loads((tmp_path / "bench_x.manifest.json").read_text())
    assert man["overrides"] == ["a=1"] and man["command"].startswith("python ") and man["date"]
    write_result_markdown("bench_x", ["| a |", "|---|", "| 1 |"], folder=tmp_path)
    assert (tmp_path / "bench_x.md").read_text() == "| a |\n|---|\n| 1 |\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench_x.json", "bench_x.manifest.json", "bench_x.md"]


def test_a_folder_result_gets_the_folder_manifest(tmp_path):
    (tmp_path / "loo_run").mkdir()
    write_result("loo_run", {"ok": True}, folder=tmp_path)
    assert (tmp_path / "loo_run" / "manifest.json").is_file()


def test_the_inventory_names_a_retired_script_without_its_missing_path(tmp_path):
    """A result whose script was retired is described by the script's name and the commit that holds
    it, in the 'what' and the 'command' cells, never by a path that no longer exists."""
    results = tmp_path / "experiments" / "results"
    (tmp_path / "experiments" / "bench").mkdir(parents=True)
    (tmp_path / "experiments" / "bench" / "bench_kept.py").write_text("")
    write_result("bench_kept_h100", {"x": 1}, folder=results)
    write_result("old_study", {"x": 1}, folder=results)
    man = results / "old_study.manifest.json"
    man.write_text(json.dumps({**json.loads(man.read_text()), "command": f"python {EXP}/analysis/old_study.py --n 2"}))
    rows = {Path(r[0].split("]")[0].lstrip("[")).stem: r for r in
            results_inventory(results, suffixes={"h100": "on one H100 GPU"}, retired={"analysis/old_study.py": "abc1234"})}
    assert rows["bench_kept_h100"][1] == f"`{EXP}/bench/bench_kept.py`, on one H100 GPU"
    assert rows["old_study"][1] == "`old_study.py` (retired; in git at abc1234)"
    assert rows["old_study"][2] == "`python old_study.py (retired; in git at abc1234) --n 2`"
    assert "experiments/analysis" not in " ".join(rows["old_study"])


def test_describe_result_reads_writers_and_sweeps():
    scripts = {"bench_loo": "bench/bench_loo.py"}
    assert describe_result(Path("loo_seams_summary_17folds.json"), scripts, {"loo_seams_summary": "analysis/seam_summary.py"}) \
        == "`experiments/analysis/seam_summary.py`, 17folds"
    assert describe_result(Path("loo_default/bench_loo.json"), scripts).endswith("run `default`")
    assert describe_result(Path("unknown.json"), scripts) == ""


def test_run_convsynth_times_a_fresh_process_and_check_names_its_failure(tmp_path):
    import pytest

    from convsynth_jax.manifest import run_convsynth

    ok = run_convsynth(["--help"], cache=tmp_path)
    assert ok.returncode == 0 and ok.check() is ok and "task" in ok.stdout
    assert ok.wall_s > 0 and ok.cpu_s > 0 and len(ok.load_avg_1min) == 2
    bad = run_convsynth(["task=no_such_task"], out_dir=tmp_path / "out", cache=tmp_path)
    assert bad.returncode != 0
    with pytest.raises(SystemExit, match="no_such_task"):
        bad.check()


def test_process_memory_reads_the_resident_set_and_its_peak():
    import sys

    import pytest

    from convsynth_jax.manifest import peak_rss_mb, process_memory_mb, reset_peak_rss

    if not sys.platform.startswith("linux"):
        pytest.skip("/proc/self/status is Linux's")
    rss, hwm = process_memory_mb("VmRSS"), process_memory_mb("VmHWM")
    assert 0 < rss <= hwm <= peak_rss_mb() + 1.0
    assert np.isnan(process_memory_mb("NoSuchField"))
    block = np.ones(128 * 2**20 // 8)                     # 128 MiB touched, then given back
    with_block = process_memory_mb("VmHWM")
    assert with_block >= rss + 100
    del block
    if reset_peak_rss():                                  # the peak is now what is resident, without the block
        assert process_memory_mb("VmHWM") < with_block - 100
