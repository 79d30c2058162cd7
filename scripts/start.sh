#!/usr/bin/env bash
# Quick start: install what is missing, build (Release), and run Reconduit on
# http://localhost:8080 with an embedded SQLite database and a local ./data folder.
#
# One reconduit-server and one reconduit-worker run in the foreground of this script; Ctrl-C
# (or SIGTERM) stops both. Every setting of the two programs can be given as an environment
# variable (see `build/release/server/reconduit-server --help` and `.../reconduit-worker --help`),
# e.g.
#   RECONDUIT_PORT=9000 RECONDUIT_DATA=/srv/reconduit bash scripts/start.sh
# or in one configuration file read by both programs (top-level names such as `data` for both,
# `[server]` and `[worker]` sections for each; see README.md, "Server configuration"):
#   RECONDUIT_CONFIG=/etc/reconduit/reconduit.conf bash scripts/start.sh
# Without RECONDUIT_DATA or RECONDUIT_CONFIG the data folder is ./data.
set -euo pipefail
cd "$(dirname "$0")/.."

bash docker/install-deps.sh build
# three.js for the page's 3D view, from npm as pinned in web/.deps/package-lock.json.
bash scripts/web_deps.sh
cmake --preset release >/dev/null
cmake --build --preset release --target reconduit-server reconduit-worker

# The data folder: RECONDUIT_DATA, else the config file's (an exported RECONDUIT_DATA would
# override the file), else ./data. Both programs create it when missing.
if [[ -z "${RECONDUIT_DATA:-}" && -z "${RECONDUIT_CONFIG:-}" ]]; then
  export RECONDUIT_DATA="$PWD/data"
fi

build/release/worker/reconduit-worker &
worker_pid=$!
build/release/server/reconduit-server &
server_pid=$!

stop() {
  kill -TERM "$server_pid" "$worker_pid" 2>/dev/null || true
  wait "$server_pid" "$worker_pid" 2>/dev/null || true
}
trap stop INT TERM EXIT
# Exit (and stop the other) as soon as either program exits.
wait -n "$server_pid" "$worker_pid"
