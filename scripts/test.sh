#!/usr/bin/env bash
# Installs what is missing, builds everything (Release, warnings as errors) and runs the whole
# test suite: unit tests beside their code and the cross-module tests in tests/.
# Exits non-zero on any failure. Longer evaluations are not part of this suite: see README
# ("Benchmarks and long evaluations"). Prints how long each step took.
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$(date +%s)
took() { local now; now=$(date +%s); echo "test.sh: $1 took $((now - t0)) s"; t0=$now; }

bash docker/install-deps.sh test
took "installing packages"
# three.js for the page's 3D view (web/.deps/package-lock.json, copied into web/vendor/).
bash scripts/web_deps.sh
took "npm ci (web/.deps)"
# playwright-core for the web page's browser test, as pinned in tests/web/package-lock.json
# (again only when the lock file is newer than what is installed).
if [ ! tests/web/node_modules/.package-lock.json -nt tests/web/package-lock.json ]; then
  npm ci --prefix tests/web --no-audit --no-fund --loglevel=error
fi
took "npm ci (tests/web)"
# gltf-validator, three and playwright-core for the model.glb test, as pinned in
# tests/gltf/package-lock.json.
if [ ! tests/gltf/node_modules/.package-lock.json -nt tests/gltf/package-lock.json ]; then
  npm ci --prefix tests/gltf --no-audit --no-fund --loglevel=error
fi
took "npm ci (tests/gltf)"
cmake --preset ci >/dev/null
cmake --build --preset ci
took "building (ci preset)"
ctest --preset ci -j "$(nproc)" --label-exclude long
took "running the tests"
