#!/usr/bin/env bash
# The Python package in CI: build the wheel with maturin, install it with its
# test and Ray extras into a fresh virtual environment, run its pytest suite
# (arrays, frames against the reference, errors, jobs, shards, the Ray
# fan-out on a local loopback cluster), mypy over examples/python/ and
# examples/python/path_stats.py.
# Everything comes from PyPI and crates.io; nothing is installed outside
# the temporary directory.
#
#   scripts/python_check.sh [--no-lint]
#
# --no-lint: skip the package's Rust fmt and clippy (`.ci/run` runs them in
# its fmt and clippy steps).
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python=${PYTHON:-python3}
if [ "${1:-}" != --no-lint ]; then
  # The package's Rust side is its own workspace: format and lint it here.
  cargo fmt --manifest-path crates/bindings/python/Cargo.toml -- --check
  CARGO_TARGET_DIR="$PWD/target" cargo clippy --manifest-path crates/bindings/python/Cargo.toml \
    --all-targets -- -D warnings
fi
# The package's lock file pins every crate it shares with the main
# workspace at a version the main lock file has: then (with the same
# release profile) maturin reuses the main release build's dependencies.
"$python" - <<'PY'
import sys, tomllib
def versions(path):
    out = {}
    with open(path, "rb") as f:
        for p in tomllib.load(f)["package"]:
            out.setdefault(p["name"], set()).add(p["version"])
    return out
main = versions("Cargo.lock")
package = versions("crates/bindings/python/Cargo.lock")
drift = sorted(f"{n} {v} (main: {', '.join(sorted(main[n]))})"
               for n, vs in package.items() if n in main for v in vs if v not in main[n])
if drift:
    sys.exit("python_check: crates/bindings/python/Cargo.lock differs from Cargo.lock: "
             + "; ".join(drift)
             + " (cargo update --manifest-path crates/bindings/python/Cargo.toml -p NAME --precise VERSION)")
PY
"$python" -m venv "$work/build"
"$work/build/bin/pip" install --quiet --disable-pip-version-check "maturin>=1.9,<2"
# The workspace's target directory: the release build of the library's
# dependencies is reused (the package is its own workspace, built by maturin).
CARGO_TARGET_DIR="$PWD/target" "$work/build/bin/maturin" build --release \
  -m crates/bindings/python/Cargo.toml --out "$work/wheels"
wheel=$(ls "$work"/wheels/shadowcull-*.whl)
# One wheel for every CPython from 3.9 on: the stable ABI's tag.
case "$wheel" in
  *-cp39-abi3-*) ;;
  *) echo "python_check: $wheel is not an abi3 wheel" >&2; exit 1 ;;
esac
"$python" -m venv "$work/venv"
"$work/venv/bin/pip" install --quiet --disable-pip-version-check "$wheel[test,ray]"
# Ray: no usage reports (the machines have no network but the registries).
export RAY_USAGE_STATS_ENABLED=0
(cd "$work" && "$work/venv/bin/python" -m pytest -q -p no:cacheprovider "$OLDPWD/crates/bindings/python/tests")
# The package is typed (py.typed, inline hints): mypy accepts the examples.
"$work/venv/bin/python" -m mypy --cache-dir "$work/mypy" examples/python/
"$work/venv/bin/python" -c "import shadowcull as sc; help(sc.Pipeline.close)" > /dev/null
line=$("$work/venv/bin/python" examples/python/path_stats.py --out "$work/path_stats.png" | tail -n 1)
echo "path_stats: $line"
test -s "$work/path_stats.png"
