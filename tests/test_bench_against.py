"""experiments/benchmarks/bench_against.py: its stage-by-stage run of the single env times every stage it names, and
its arguments are checked."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "benchmarks"))

import bench_against  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def test_the_stage_run_times_every_stage_of_the_single_env_in_alarm():
    result = bench_against.measure(ROOT, "alarm", 1, steps=3, warmup=12, seed=0, stages=True)
    stages = {stage for *_, stage in bench_against.STAGES}
    assert set(result["stages_us"]) == stages | {"other"}
    # every wrapped method runs at every step in alarm: a stage whose method was renamed or not reached reads 0
    assert all(result["stages_us"][stage] > 0 for stage in stages)
    assert result["env_steps_per_s"] == pytest.approx(1e6 / result["step_us"])


def test_stages_with_a_batch_size_is_refused(capsys):
    with pytest.raises(SystemExit) as exited:
        bench_against.main(["--stages", "--size", "4"])
    assert exited.value.code == 2
    assert "--size" in capsys.readouterr().err
