"""Fan a batch job out over a Ray cluster: one Ray task per shard, then a merge.

    python -m shadowcull.distributed JOB --out DIR --shards N [--address ADDR]
        [--warmup W] [--keyframe K] [--frames F]

Each task calls :func:`shadowcull.run_job` with ``shard=(i, N)`` into
``DIR/shards/<i>``; the driver then merges the shard directories into
``DIR`` with :func:`shadowcull.merge`. The result obeys the sharding
contract of ``shadowcull run --shard``: masks and mask-derived columns equal
the single run's byte for byte, and with ``--keyframe K`` on the shard
boundaries every column but the times.

Where the data lives: the job file, the scene files it names and ``DIR``
must be on a filesystem every node of the cluster sees under the same path
(NFS, a cluster filesystem, or one machine). Paths are made absolute on the
driver and shipped to the tasks as text; nothing large passes through Ray's
object store, so a shard's masks are written once, by the node that made
them. A task that fails raises its error (``ValueError``, ``OSError``) on
the driver, naming the shard.

Without ``--address`` a local Ray instance is started on loopback
(127.0.0.1, no dashboard) and stopped at the end; with one, the driver joins
that cluster (``ray://host:10001`` or ``host:6379``, as ``ray.init`` takes).
Each task asks Ray for ``--cpus-per-shard`` CPUs (default 1) and runs the
pipeline on that many threads.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional

import shadowcull


def _run_shard(
    job: Optional[str],
    out: str,
    index: int,
    count: int,
    frames: Optional[int],
    warmup: Optional[int],
    keyframe: Optional[int],
    threads: int,
) -> Dict[str, Any]:
    """One Ray task: shard ``index`` of ``count``. Runs on a worker node."""
    # The shard runs on the CPUs Ray gave it, not on every core of the node.
    os.environ.setdefault("RAYON_NUM_THREADS", str(threads))
    started = time.perf_counter()
    summary = shadowcull.run_job(
        job, out=out, frames=frames, shard=(index, count), warmup=warmup, keyframe=keyframe
    )
    return {"shard": index, "out": out, "seconds": time.perf_counter() - started, "frames": summary["frames"]}


def run_distributed(
    job: "os.PathLike[str] | str | None",
    out: "os.PathLike[str] | str",
    shards: int,
    *,
    address: Optional[str] = None,
    frames: Optional[int] = None,
    warmup: Optional[int] = None,
    keyframe: Optional[int] = None,
    cpus_per_shard: int = 1,
) -> Dict[str, Any]:
    """Runs ``job`` (the bundled default when None) as ``shards`` Ray tasks
    and merges them into ``out``; returns the merge report with the shards'
    wall times (``shard_seconds``) and the whole run's (``seconds``)."""
    if shards < 1:
        raise ValueError(f"shards: {shards} must be at least 1")
    if cpus_per_shard < 1:
        raise ValueError(f"cpus_per_shard: {cpus_per_shard} must be at least 1")
    import ray  # the optional dependency `shadowcull[ray]`

    started = time.perf_counter()
    out_dir = Path(out).resolve()
    job_path = None if job is None else str(Path(job).resolve())
    if job_path is not None and not Path(job_path).is_file():
        raise OSError(f"{job_path}: no such job file")
    shard_dirs = [out_dir / "shards" / str(i) for i in range(shards)]
    own_cluster = not ray.is_initialized()
    if own_cluster:
        # No usage reports: the cluster may have no network beyond its nodes.
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        if address is None:
            ray.init(
                include_dashboard=False,
                _node_ip_address="127.0.0.1",
                logging_level="warning",
                log_to_driver=True,
            )
        else:
            ray.init(address=address, logging_level="warning", log_to_driver=True)
    try:
        task = ray.remote(num_cpus=cpus_per_shard, max_retries=0)(_run_shard)
        refs = [
            task.remote(job_path, str(d), i, shards, frames, warmup, keyframe, cpus_per_shard)
            for i, d in enumerate(shard_dirs)
        ]
        results: List[Dict[str, Any]] = []
        for i, ref in enumerate(refs):
            try:
                results.append(ray.get(ref))
            except ray.exceptions.RayTaskError as e:
                # The library's own error, raised in the task: name the shard.
                cause = getattr(e, "cause", None)
                if not isinstance(cause, (OSError, ValueError)):
                    raise
                kind = OSError if isinstance(cause, OSError) else ValueError
                raise kind(f"shard {i}/{shards}: {cause}") from None
    finally:
        if own_cluster:
            ray.shutdown()
    report = shadowcull.merge(out_dir, shard_dirs)
    report["shard_seconds"] = [r["seconds"] for r in sorted(results, key=lambda r: r["shard"])]
    report["seconds"] = time.perf_counter() - started
    return report


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m shadowcull.distributed",
        description="Run a shadowcull batch job as N shards on a Ray cluster and merge them.",
    )
    parser.add_argument("job", nargs="?", help="the RON job file (default: the bundled default job)")
    parser.add_argument("--out", required=True, help="output directory (shared by every node)")
    parser.add_argument("--shards", type=int, required=True, help="number of shards (Ray tasks)")
    parser.add_argument("--address", help="an existing Ray cluster to join (default: start a local one)")
    parser.add_argument("--frames", type=int, help="run only the job's first F frames")
    parser.add_argument("--warmup", type=int, help="warm-up frames before each shard's block")
    parser.add_argument("--keyframe", type=int, help="reset the culling histories every K frames")
    parser.add_argument("--cpus-per-shard", type=int, default=1, help="CPUs each task asks Ray for")
    args = parser.parse_args(argv)
    try:
        report = run_distributed(
            args.job,
            args.out,
            args.shards,
            address=args.address,
            frames=args.frames,
            warmup=args.warmup,
            keyframe=args.keyframe,
            cpus_per_shard=args.cpus_per_shard,
        )
    except (ValueError, OSError) as e:
        print(f"shadowcull.distributed: {e}", file=sys.stderr)
        return 1
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
