#!/usr/bin/env bash
# The web page's modules from npm (three.js for the 3D view), as pinned in
# web/.deps/package-lock.json: installs them with `npm ci` into web/.deps/node_modules (only
# when the lock file is newer than what is installed), then copies the few files the page
# loads into web/vendor/ (generated, not in git), where index.html's import map points.
#
# Why a copy instead of serving node_modules: reconduit-server serves everything below web/
# from the same origin as the API, so any file a package ships (an HTML demo, a stray script)
# would become a page that can call the API. Only the allow-list below is served; web/.deps
# itself never is (the static handler refuses path segments starting with '.'), and nothing is
# fetched from a CDN at run time. GLTFLoader imports its helpers by relative path, so the
# files keep their place in the package's layout.
#
# Called by scripts/start.sh, scripts/test.sh and docker/Dockerfile; needs npm (installed by
# docker/install-deps.sh build).
set -euo pipefail
cd "$(dirname "$0")/.."

deps=web/.deps
if [ ! "$deps/node_modules/.package-lock.json" -nt "$deps/package-lock.json" ]; then
  npm ci --prefix "$deps" --no-audit --no-fund --loglevel=error
fi

# What the page imports (web/viewer.js) and what those files import in turn.
three_files=(
  LICENSE
  package.json
  build/three.module.js
  build/three.core.js
  examples/jsm/controls/OrbitControls.js
  examples/jsm/loaders/GLTFLoader.js
  examples/jsm/utils/BufferGeometryUtils.js
  examples/jsm/utils/SkeletonUtils.js
)
out=web/vendor/three
rm -rf "$out.tmp"
for f in "${three_files[@]}"; do
  install -D -p -m 0644 "$deps/node_modules/three/$f" "$out.tmp/$f"
done
rm -rf "$out"
mv "$out.tmp" "$out"
