"""Shared fixtures of the Python package's tests: the repository's paths, the
small job, a box scene built from arrays, and the sharding contract."""

import csv
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[3]  # crates/bindings/python/tests -> the workspace root
SHARED = ROOT.parent / "shared" / "data"
SMALL_JOB = HERE / "data" / "small_city.ron"


@pytest.fixture
def small_job() -> Path:
    return SMALL_JOB


@pytest.fixture
def shared_data() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} is absent (a user's clone): shared-scene tests skipped")
    return SHARED


def cube_arrays():
    """A unit cube: 8 corners (x, y, z = bits 0, 1, 2 of the index), 12 triangles."""
    corners = np.array([[i & 1, i >> 1 & 1, i >> 2 & 1] for i in range(8)], np.float32)
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    tris = np.array([t for a, b, c, d in faces for t in ([a, b, c], [a, c, d])], np.uint32)
    return corners, tris


def quad_arrays(size=9.0):
    """A ground quad at y = 0 facing +y."""
    s = size
    return (
        np.array([[-s, 0, -s], [-s, 0, s], [s, 0, s], [s, 0, -s]], np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.int64),
    )


def translation(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def read_stats(directory: Path):
    with open(directory / "stats.csv", newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def assert_same_run(single: Path, merged: Path, every_column: bool):
    """The sharding contract: every PNG byte for byte, and the mask-derived
    columns (with `every_column`, every column but the times) equal."""
    mask_cols = {"lit", "shadow", "unlit", "background", "ambiguous", "shadowed_pixels",
                 "mismatch_pixels", "mismatch_off_boundary", "ambiguous_pixels", "compared_pixels"}
    head_a, rows_a = read_stats(single)
    head_b, rows_b = read_stats(merged)
    assert head_a == head_b
    assert len(rows_a) == len(rows_b) > 0
    checked = [i for i, c in enumerate(head_a)
               if ((not c.endswith("_ms")) if every_column else (c in mask_cols))]
    assert len(checked) >= len(mask_cols)
    for a, b in zip(rows_a, rows_b):
        for i in checked:
            assert a[i] == b[i], f"frame {a[0]} light {a[1]}: column {head_a[i]}: {a[i]} != {b[i]}"
    images_a = sorted(p.name for p in (single / "frames").glob("*.png"))
    images_b = sorted(p.name for p in (merged / "frames").glob("*.png"))
    assert images_a == images_b and images_a
    for name in images_a:
        assert (single / "frames" / name).read_bytes() == (merged / "frames" / name).read_bytes(), name
