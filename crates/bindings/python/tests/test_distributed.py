"""`python -m shadowcull.distributed` on a local Ray cluster (loopback only):
two Ray tasks, merged, equal the single run under the sharding contract."""

import json
import os
import subprocess
import sys

import pytest

import shadowcull as sc
from conftest import assert_same_run

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install shadowcull[ray])")


def test_two_ray_shards_equal_the_single_run(small_job, tmp_path):
    sc.run_job(small_job, out=tmp_path / "single")
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    run = subprocess.run(
        [sys.executable, "-m", "shadowcull.distributed", str(small_job),
         "--out", str(tmp_path / "ray"), "--shards", "2"],
        capture_output=True, text=True, env=env, timeout=600,
    )
    assert run.returncode == 0, run.stderr[-4000:]
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert (report["shards"], report["frames"], report["rows"]) == (2, 8, 16)
    assert len(report["shard_seconds"]) == 2
    # The shard boundary (frame 4) is a keyframe of the job: every column but
    # the times and every image equal the single run's.
    assert_same_run(tmp_path / "single", tmp_path / "ray", every_column=True)


def test_a_failing_shard_is_named(tmp_path):
    from shadowcull.distributed import run_distributed

    bad = tmp_path / "bad.ron"
    bad.write_text("(version: 1, scene: City(()), resolution: (64, 64), pipeline: (tile: 5))")
    with pytest.raises(ValueError, match="shard 0/1.*tile"):
        run_distributed(bad, tmp_path / "out", 1)
