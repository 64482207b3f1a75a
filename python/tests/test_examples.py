"""The examples under examples/python run (the benchmark on a small frame: timed, not judged)."""

import subprocess
import sys

from conftest import ROOT, shared_dir, skip_or_fail


def test_calibrate_example_runs(tmp_path):
    dng = shared_dir() / "data" / "colorchart.dng"
    if not dng.exists():
        skip_or_fail(f"{dng} is absent (the project's shared data)")
    out = subprocess.run(
        [sys.executable, str(ROOT / "examples/python/calibrate.py"), str(dng), "--out",
         str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "chosen: nsrm.Model" in out.stdout
    assert (tmp_path / "model.json").exists() and (tmp_path / "model.cube").exists()


def test_bench_example_runs_on_a_small_frame():
    out = subprocess.run(
        [sys.executable, str(ROOT / "examples/python/bench.py"), "--size", "64x48", "--reps", "1"],
        capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "ratios" in out.stdout
