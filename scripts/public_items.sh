#!/usr/bin/env bash
# Counts each library crate's public API from rustdoc's JSON (nightly toolchain):
# the names a user can reach by path (types, functions, constants, traits,
# macros, modules), and all public items including methods, fields and variants.
#
# Usage: scripts/public_items.sh [FEATURES...]   (e.g. test-util)
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}/public-items
features=${1:-}
printf '%-24s %8s %8s\n' crate paths items
for pkg in shadowcull-scene shadowcull-raster shadowcull-shadowgen shadowcull-visibility shadowcull; do
  args=()
  if [ -n "$features" ] && cargo metadata --no-deps --format-version 1 |
    python3 -c "import json,sys; m=json.load(sys.stdin); p=[p for p in m['packages'] if p['name']=='$pkg'][0]; sys.exit(0 if '$features' in p['features'] else 1)"; then
    args=(--features "$features")
  fi
  CARGO_TARGET_DIR=$target cargo +nightly rustdoc -q -p "$pkg" --lib "${args[@]}" -- \
    -Z unstable-options --output-format json 2>/dev/null
  name=$(cargo metadata --no-deps --format-version 1 | python3 -c "
import json, sys
m = json.load(sys.stdin)
p = [p for p in m['packages'] if p['name'] == '$pkg'][0]
print([t['name'] for t in p['targets'] if 'lib' in t['kind']][0].replace('-', '_'))")
  python3 - "$target/doc/$name.json" "$pkg" <<'EOF'
import json, sys
doc = json.load(open(sys.argv[1]))
# Items of this crate reachable by a public path (re-exports resolved).
paths = [p for p in doc["paths"].values() if p["crate_id"] == 0 and p["kind"] != "module"]
# Every public item of this crate rustdoc documents, minus impl blocks and
# re-export (`use`) items, which are not items a user names.
items = [i for i in doc["index"].values() if i["crate_id"] == 0
         and not any(k in i["inner"] for k in ("impl", "use", "module"))]
print(f"{sys.argv[2]:<24} {len(paths):>8} {len(items):>8}")
EOF
done
