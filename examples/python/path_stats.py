"""Per-frame stage times and PSR/PSC counts of a camera path, plotted to a PNG.

Loads a scene (default: the shared box city `city_4096.txt` with its
`street` camera path and its point light), adds a sun, runs the camera along
the scene's path (or once around the scene when it names none) and plots,
per frame, the pipeline's stage times (eye pass, light passes,
silhouettes and volumes, stencil) and the culling counts (PSR; PSC per
light) with matplotlib. Prints one JSON line of totals.

    python examples/python/path_stats.py [SCENE] [--frames N] [--size WxH] [--out PNG]

Needs the `shadowcull` package (see README "From Python") and matplotlib.
"""

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import shadowcull as sc  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SCENE = ROOT.parent / "shared" / "data" / "bench" / "city_4096.txt"


def orbit(lo, hi, frames):
    """Camera poses once around the bounds' centre, looking slightly down."""
    centre = (lo + hi) / 2
    radius = 0.75 * np.linalg.norm((hi - lo)[[0, 2]])
    height = centre[1] + 0.6 * (hi[1] - lo[1]) + 0.15 * radius
    for i in range(frames):
        a = 2 * np.pi * i / frames
        eye = centre + np.array([radius * np.cos(a), height - centre[1], radius * np.sin(a)])
        yield sc.look_at(eye, centre, fov_y_deg=50.0, near=0.05 * radius / 10)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--out", default="path_stats.png")
    args = ap.parse_args(argv)
    if not Path(args.scene).exists():
        sys.exit(f"path_stats: {args.scene} does not exist; pass a .gltf, .glb, .obj or box-city scene")
    width, height = (int(v) for v in args.size.lower().split("x"))

    p = sc.Pipeline(culling="chcpp", stencil="h", reference_every=0)
    loaded = p.load(args.scene)
    # The scene's own point light (or one above the scene), and a sun.
    if loaded.lights:
        lamp = p.add_light("named", loaded.lights[0])
    else:
        lamp = p.add_light("above_scene", 1.5)
    sun = p.add_light("sun", elevation_deg=35.0, azimuth_deg=30.0)
    lights = {lamp: "point", sun: "sun"}
    if loaded.paths:
        path = "street" if "street" in loaded.paths else loaded.paths[0]
        cameras = [c for c in (p.path_camera(path, i) for i in range(args.frames)) if c is not None]
    else:
        path = "orbit"
        cameras = list(orbit(*p.bounds, args.frames))

    rows = []
    for camera in cameras:
        f = p.frame(width, height, camera=camera)
        ls = f.light_stats
        rows.append({
            "eye": f.stats["eye_ms"],
            "light": sum(ls[l]["light_ms"] for l in lights),
            "volumes": sum(ls[l]["silhouette_ms"] + ls[l]["volume_ms"] for l in lights),
            "stencil": sum(ls[l]["stencil_ms"] for l in lights),
            "frame": f.stats["frame_ms"],
            "psr": len(f.psr),
            **{f"psc_{name}": len(f.psc[l]) for l, name in lights.items()},
        })

    x = np.arange(len(rows))
    col = lambda k: np.array([r[k] for r in rows])  # noqa: E731
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    # Per-light stages are summed over the lights, which may run in parallel:
    # their sum can exceed the whole frame's wall time.
    names = {"eye": "eye pass", "light": "light passes (PSC), Σ lights",
             "volumes": "silhouettes + volumes, Σ lights", "stencil": "stencil + mask, Σ lights"}
    for key, label in names.items():
        top.plot(x, col(key), label=label)
    top.plot(x, col("frame"), "k-", lw=1.5, label="whole frame (wall)")
    top.set_ylabel("ms per frame")
    top.legend(loc="upper right", fontsize=8)
    top.set_title(f"{Path(args.scene).name}, camera path '{path}': {len(loaded.objects)} objects, "
                  f"{width}×{height}, CHC++ + hierarchical stencil")
    bottom.plot(x, col("psr"), label="PSR (receivers)")
    for name in lights.values():
        bottom.plot(x, col(f"psc_{name}"), label=f"PSC ({name} light)")
    bottom.axhline(len(loaded.objects), color="grey", ls=":", label="objects in the scene")
    bottom.set_yscale("log")
    bottom.set_xlabel("frame")
    bottom.set_ylabel("objects")
    bottom.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(json.dumps({
        "scene": str(args.scene),
        "objects": int(len(loaded.objects)),
        "path": path,
        "frames": len(rows),
        "frame_ms_median": float(np.median(col("frame"))),
        "psr_mean": float(col("psr").mean()),
        **{f"psc_{n}_mean": float(col(f"psc_{n}").mean()) for n in lights.values()},
        "plot": str(args.out),
    }))


if __name__ == "__main__":
    main()
