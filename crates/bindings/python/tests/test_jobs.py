"""Batch jobs from Python: run_job, shards and merge under the sharding
contract of `shadowcull run --shard`."""

import json

import pytest

import shadowcull as sc
from conftest import assert_same_run, read_stats


def test_run_job_writes_a_run(small_job, tmp_path):
    summary = sc.run_job(small_job, out=tmp_path / "single")
    assert summary["frames"] == 8
    assert summary["check_totals"]["mismatch_pixels"] == 0
    assert summary["check_totals"]["compared_pixels"] > 0
    assert json.loads((tmp_path / "single" / "summary.json").read_text())["frames"] == 8
    head, rows = read_stats(tmp_path / "single")
    assert len(rows) == 16 and head[:2] == ["frame", "light"]


def test_frames_cut_a_run(small_job, tmp_path):
    summary = sc.run_job(small_job, out=tmp_path / "cut", frames=2)
    assert summary["frames"] == 2
    assert len(read_stats(tmp_path / "cut")[1]) == 4


@pytest.mark.parametrize("shards", [2, 3])
def test_merged_shards_equal_the_single_run(small_job, tmp_path, shards):
    sc.run_job(small_job, out=tmp_path / "single")
    dirs = [tmp_path / f"shard{i}" for i in range(shards)]
    for i, d in enumerate(dirs):
        sc.run_job(small_job, out=d, shard=(i, shards))
    report = sc.merge(tmp_path / "merged", dirs)
    assert (report["shards"], report["frames"], report["rows"]) == (shards, 8, 16)
    # Two shards split at frame 4, a keyframe: every column but the times is
    # equal. Three split at 3 and 6, inside keyframe intervals: the masks and
    # the mask-derived columns are.
    assert_same_run(tmp_path / "single", tmp_path / "merged", every_column=shards == 2)


def test_merge_names_a_missing_shard(small_job, tmp_path):
    sc.run_job(small_job, out=tmp_path / "s0", shard=(0, 2))
    with pytest.raises(ValueError, match="1/2"):
        sc.merge(tmp_path / "merged", [tmp_path / "s0"])
